"""Found by fuzzing: `bench reproduce`, `bench hums fit|sweep|rul|campaign`
checked their output options only when writing them, after minutes of work (exit 1,
FileExistsError / FileNotFoundError / IsADirectoryError, a --doc with unbalanced markers
refused at the end), and a negative --seed failed in numpy (exit 1 ValueError) in
`bench hums prognose`, `bench hums campaign` and `bench fleet synth`.

Every long step is stubbed by one that fails with "the work started": a bad option must
fail before it, in one line, with exit 2; a good one must get to it (creating nothing)."""

from __future__ import annotations

import time

import pytest
from cli_errors import stub_steps

from bench import BenchError
from bench.cli import main

STARTED = "the work started"


@pytest.fixture
def stub_work(monkeypatch, tmp_path):
    """The long steps of reproduce, hums and fleet synth raise BenchError(STARTED)."""
    stub_steps(monkeypatch, (("bench.studies.reproduce", "run"), ("bench.hums.monitor", "fitted"),
                             ("bench.hums.sweep", "run"), ("bench.hums.rul_run", "run_rul"),
                             ("bench.hums.campaign", "run_campaign"),
                             ("bench.hums.prognosis_campaign", "run_usage_campaign"),
                             ("bench.hums.prognosis_trends", "load_calibration"),
                             ("bench.hums.prognosis_trends", "prognose_trends"),
                             ("bench.hums.trend_io", "read_table"),
                             ("bench.fleet.synth", "synth")),
               BenchError(STARTED))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))    # the default cal path
    monkeypatch.chdir(tmp_path)              # reproduce's default --out and --figures


def _paths(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    doc = tmp_path / "half.md"
    doc.write_text("# doc\n<!-- sweep:begin -->\n<!-- rul-noise:begin -->\n"
                   "<!-- usage-campaign:end -->\n<!-- campaign:begin -->\n")
    binary = tmp_path / "binary.md"
    binary.write_bytes(b"\xff\xfe\x00bad")
    return {"tmp": tmp_path, "afile": afile, "missing": tmp_path / "no" / "dir",
            "doc": doc, "binary": binary}


BAD = {
    "reproduce-out-under-a-file": (
        ["reproduce", "--out", "{afile}/sub"],
        "--out: cannot write into {afile}/sub: {afile} is not a directory"),
    "reproduce-out-read-only": (
        ["reproduce", "--out", "/proc/bench-x"],
        "--out: cannot write into /proc/bench-x: directory /proc is not writable"),
    "reproduce-out-a-file": (
        ["reproduce", "--out", "{afile}"], "--out: cannot write into {afile}: it is not a "
        "directory"),
    "reproduce-doc-no-dir": (
        ["reproduce", "--doc", "{missing}/r.md"],
        "--doc: cannot write {missing}/r.md: directory {missing} does not exist"),
    "reproduce-doc-not-markdown": (
        ["reproduce", "--doc", "{tmp}/r.txt"], "--doc: {tmp}/r.txt: unknown suffix '.txt'"),
    "reproduce-json-no-dir": (
        ["reproduce", "--json", "{missing}/r.json"],
        "--json: cannot write {missing}/r.json: directory {missing} does not exist"),
    "reproduce-json-read-only": (
        ["reproduce", "--json", "/proc/r.json"],
        "--json: cannot write /proc/r.json: directory /proc is not writable"),
    "reproduce-figures-a-file": (
        ["reproduce", "--figures", "{afile}"],
        "--figures: cannot write into {afile}: it is not a directory"),
    "reproduce-figures-read-only": (
        ["reproduce", "--figures", "/proc/figs"],
        "--figures: cannot write into /proc/figs: directory /proc is not writable"),
    "fit-json-under-a-file": (
        ["hums", "fit", "--json", "{afile}/f.json"],
        "--json: cannot write {afile}/f.json: {afile} is not a directory"),
    "fit-json-a-dir": (
        ["hums", "fit", "--json", "{tmp}"], "--json: cannot write {tmp}: it is a directory"),
    "sweep-figures-a-file": (
        ["hums", "sweep", "--figures", "{afile}"],
        "--figures: cannot write into {afile}: it is not a directory"),
    "sweep-doc-under-a-file": (
        ["hums", "sweep", "--doc", "{afile}/d.md"],
        "--doc: cannot write {afile}/d.md: {afile} is not a directory"),
    "sweep-doc-unbalanced": (
        ["hums", "sweep", "--doc", "{doc}"],
        "--doc: {doc}: unbalanced generated-section markers for 'sweep'"),
    "sweep-doc-not-text": (
        ["hums", "sweep", "--doc", "{binary}"], "--doc: {binary}: cannot read it as text"),
    "rul-figures-read-only": (
        ["hums", "rul", "--figures", "/proc/figs"],
        "--figures: cannot write into /proc/figs: directory /proc is not writable"),
    "rul-noise-doc-unbalanced": (
        ["hums", "rul", "--noise", "--doc", "{doc}"],
        "--doc: {doc}: unbalanced generated-section markers for 'rul-noise'"),
    "rul-json-read-only": (
        ["hums", "rul", "--json", "/proc/x/r.json"],
        "--json: cannot write /proc/x/r.json: directory /proc is not writable"),
    "campaign-json-under-a-file": (
        ["hums", "campaign", "--json", "{afile}/a/c.json"],
        "--json: cannot write {afile}/a/c.json: {afile} is not a directory"),
    "campaign-doc-unbalanced": (
        ["hums", "campaign", "--doc", "{doc}"],
        "--doc: {doc}: unbalanced generated-section markers for 'campaign'"),
    "campaign-figures-a-file": (
        ["hums", "campaign", "--figures", "{afile}"],
        "--figures: cannot write into {afile}: it is not a directory"),
    "campaign-trends-out-alone": (
        ["hums", "campaign", "--trends-out", "{tmp}/t.csv"], "--trends-out is for --usage"),
    "campaign-calibration-out-alone": (
        ["hums", "campaign", "--calibration-out", "{tmp}/c.json"],
        "--calibration-out is for --usage"),
    "usage-trends-out-under-a-file": (
        ["hums", "campaign", "--usage", "--trends-out", "{afile}/t.csv"],
        "--trends-out: cannot write {afile}/t.csv: {afile} is not a directory"),
    "usage-calibration-out-read-only": (
        ["hums", "campaign", "--usage", "--calibration-out", "/proc/c.json"],
        "--calibration-out: cannot write /proc/c.json: directory /proc is not writable"),
    "usage-calibration-out-a-dir": (
        ["hums", "campaign", "--usage", "--calibration-out", "{tmp}"],
        "--calibration-out: cannot write {tmp}: it is a directory"),
    "usage-doc-unbalanced": (
        ["hums", "campaign", "--usage", "--doc", "{doc}"],
        "--doc: {doc}: unbalanced generated-section markers for 'usage-campaign'"),
    "prognose-json-under-a-file": (
        ["hums", "prognose", "--trends", "{tmp}/t.csv", "--json", "{afile}/p.json"],
        "--json: cannot write {afile}/p.json: {afile} is not a directory"),
}


def _run(args, message, paths, capsys):
    t0 = time.perf_counter()
    rc = main([a.format(**paths) for a in args])
    assert time.perf_counter() - t0 < 2.0
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert err.startswith(f"error: {message.format(**paths)}"), err
    assert len(err.splitlines()) == 1, err


@pytest.mark.parametrize("case", list(BAD))
def test_bad_option_fails_before_the_work_in_one_line(tmp_path, capsys, stub_work, case):
    paths = _paths(tmp_path)
    before = sorted(tmp_path.rglob("*"))
    _run(*BAD[case], paths, capsys)
    assert sorted(tmp_path.rglob("*")) == before        # nothing made, no probe left


GOOD = {
    "reproduce-defaults": ["reproduce"],         # out/reproduce and its figures/ made
    "reproduce-out-new-dirs": ["reproduce", "--out", "{tmp}/new/deeper",
                               "--json", "{tmp}/r.json", "--figures", "{tmp}/new/figs"],
    "reproduce-doc": ["reproduce", "--doc", "{tmp}/reproduction.md"],
    "fit-json-new-dirs": ["hums", "fit", "--json", "{tmp}/new/deeper/f.json"],
    "sweep-doc-new": ["hums", "sweep", "--doc", "{tmp}/new/hums.md", "--figures",
                      "{tmp}/new/figs", "--json", "{tmp}/s.json"],
    "sweep-doc-balanced": ["hums", "sweep", "--doc", "{tmp}/ok.md"],
    "rul-doc-other-section-unbalanced": ["hums", "rul", "--doc", "{doc}"],
    "campaign-seed-0": ["hums", "campaign", "--seed", "0", "--doc", "{tmp}/ok.md"],
    "usage-default-calibration": ["hums", "campaign", "--usage", "--trends-out",
                                  "{tmp}/new/t.csv"],
    "prognose-seed-0": ["hums", "prognose", "--trends", "{tmp}/t.csv", "--seed", "0"],
    "fleet-synth-seed-0": ["fleet", "synth", "--actuators", "1", "--days", "1", "--out",
                           "{tmp}/f"],
}


@pytest.mark.parametrize("case", list(GOOD))
def test_good_options_reach_the_work_and_make_nothing(tmp_path, capsys, stub_work, case):
    paths = _paths(tmp_path)
    (tmp_path / "ok.md").write_text("<!-- sweep:begin -->\nold\n<!-- sweep:end -->\n")
    before = sorted(tmp_path.rglob("*"))
    _run(GOOD[case], STARTED, paths, capsys)
    assert sorted(tmp_path.rglob("*")) == before


def test_output_file_with_parents_made(tmp_path):
    """`check_output_file(make_parents=True)`: missing directories are fine when they can
    be made; a dangling symlink on the way is not a directory."""
    from bench.cli.outputs import check_output_file
    deep = tmp_path / "a" / "b" / "c.json"
    assert check_output_file(deep, "--json", make_parents=True) == deep
    with pytest.raises(BenchError, match="directory .* does not exist"):
        check_output_file(deep, "--json")
    (tmp_path / "link").symlink_to(tmp_path / "nowhere")
    with pytest.raises(BenchError, match=f"{tmp_path / 'link'} is not a directory"):
        check_output_file(tmp_path / "link" / "x.json", "--json", make_parents=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link"]
