"""Output paths are checked before the long work: a bad `calibrate -o`,
`gap --json/--report`, `import -o` or `bench log FILE` fails at once, in one line, and
the fit, the diagnosis, the import or the recording never starts."""

from __future__ import annotations

import time

import pytest
from cli_errors import stub_steps

from bench.cli import main

ROFS = "/proc/bench-state-test"          # a directory no one can create files in


@pytest.fixture
def no_long_work(monkeypatch):
    """Any of the long steps starting fails the test."""
    stub_steps(monkeypatch, (("bench.gap.inputs", "load_log"),
                             ("bench.gap.calibrate", "calibrate"),
                             ("bench.gap.diagnose", "diagnose"),
                             ("bench.gap.importer", "read_map"),
                             ("bench.gap.importer", "import_table"), ("bench.bus", "find_bus"),
                             ("bench.bus", "connect")),
               AssertionError("the long work started before the output path was checked"))


def one_line(capsys, rc: int, start: str) -> None:
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert err.startswith(f"error: {start}"), err
    assert len(err.splitlines()) == 1


def _cases(tmp_path):
    missing = tmp_path / "no" / "such" / "dir"
    afile = tmp_path / "afile.txt"
    afile.write_text("x")
    log = str(tmp_path / "in.log")
    return [
        (["calibrate", log, "-o", str(missing / "c.json")],
         f"-o: cannot write {missing / 'c.json'}: directory {missing} does not exist"),
        (["calibrate", log, "-o", str(tmp_path / "c.csv")],
         f"-o: {tmp_path / 'c.csv'}: unknown suffix '.csv' (use .json)"),
        (["calibrate", log, "-o", str(tmp_path)],
         f"-o: cannot write {tmp_path}: it is a directory"),
        (["calibrate", log, "-o", f"{ROFS}/c.json"],
         f"-o: cannot write {ROFS}/c.json: directory {ROFS} does not exist"),
        (["calibrate", log, "-o", "/proc/c.json"], "-o: cannot write /proc/c.json: directory "
         "/proc is not writable"),
        (["gap", log, "--json", str(missing / "g.json")],
         f"--json: cannot write {missing / 'g.json'}: directory {missing} does not exist"),
        (["gap", log, "--json", str(tmp_path / "g.txt")],
         f"--json: {tmp_path / 'g.txt'}: unknown suffix '.txt' (use .json)"),
        (["gap", log, "--report", str(afile)],
         f"--report: cannot write into {afile}: it is not a directory"),
        (["gap", log, "--report", str(afile / "sub")],
         f"--report: cannot write into {afile / 'sub'}: {afile} is not a directory"),
        (["gap", log, "--report", "/proc/report"],
         "--report: cannot write into /proc/report: directory /proc is not writable"),
        (["import", log, "--map", log, "-o", str(tmp_path / "t.txt")],
         f"-o: {tmp_path / 't.txt'}: unknown suffix '.txt' (use .npz, .csv, .parquet)"),
        (["import", log, "--map", log, "-o", str(missing / "t.npz")],
         f"-o: cannot write {missing / 't.npz'}: directory {missing} does not exist"),
        (["import", "/proc/table.csv", "--map", log],
         "-o: cannot write /proc/table.npz: directory /proc is not writable"),
        (["log", str(missing / "x.log"), "-i", "virtual", "-c", "t"],
         f"FILE.log: cannot write {missing / 'x.log'}: directory {missing} does not exist"),
        (["log", str(tmp_path / "x.csv"), "-i", "virtual", "-c", "t"],
         f"FILE.log: {tmp_path / 'x.csv'}: unknown suffix '.csv' (use .log, .asc, .blf, .trc, .mf4)"),
    ]


CASES = ["calibrate-no-dir", "calibrate-suffix", "calibrate-a-dir", "calibrate-no-dir-in-proc",
         "calibrate-read-only", "gap-json-no-dir", "gap-json-suffix", "gap-report-a-file",
         "gap-report-under-a-file", "gap-report-read-only", "import-suffix", "import-no-dir",
         "import-default-read-only", "log-no-dir", "log-suffix"]


@pytest.mark.parametrize("k", range(len(CASES)), ids=CASES)
def test_bad_output_fails_first_in_one_line(tmp_path, capsys, no_long_work, k):
    args, message = _cases(tmp_path)[k]
    t0 = time.perf_counter()
    rc = main(args)
    assert time.perf_counter() - t0 < 0.5
    one_line(capsys, rc, message)
    assert not any(p.name.startswith(".bench-probe") for p in tmp_path.iterdir())


def test_good_outputs_pass_the_check(tmp_path):
    from bench.cli.outputs import check_output_dir, check_output_file
    assert check_output_file(tmp_path / "a.json", "-o", (".json",)) == tmp_path / "a.json"
    check_output_file("-", "-o", (".json",), stdout_ok=True)
    check_output_dir(tmp_path / "new" / "deeper", "--report")
    assert not (tmp_path / "new").exists()          # checking creates nothing
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("extra, message", [
    (["--json", "{missing}/b.json"], "--json: cannot write {missing}/b.json: directory "
                                     "{missing} does not exist"),
    (["--json", "{tmp}"], "--json: cannot write {tmp}: it is a directory"),
    (["--markdown", "{missing}/b.md"], "--markdown: cannot write {missing}/b.md: directory "
                                       "{missing} does not exist"),
    (["--indie-set", "speed_window=1"], "--indie-set is for --generator independent"),
    (["--effects", ""], "--effects lists no effect"),
], ids=["json-no-dir", "json-a-dir", "markdown-no-dir", "indie-set-alone", "effects-empty"])
def test_gap_bench_arguments_are_checked_before_the_work(tmp_path, capsys, monkeypatch,
                                                         extra, message):
    """Found by fuzzing: these started the blind benchmark (minutes) and
    then failed at the end (FileNotFoundError / IsADirectoryError, exit 1), ran with the
    option ignored (--indie-set, an empty --effects) or failed in numpy (ValueError)."""
    import bench.gap.blind

    def boom(*a, **k):
        raise AssertionError("the benchmark started before its arguments were checked")
    monkeypatch.setattr(bench.gap.blind, "run", boom)
    fmt = {"tmp": tmp_path, "missing": tmp_path / "no" / "dir"}
    rc = main(["gap-bench", *(a.format(**fmt) for a in extra)])
    one_line(capsys, rc, message.format(**fmt))
