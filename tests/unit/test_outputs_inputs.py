"""No command writes over a file it reads: `bench.cli.outputs.check_io` refuses, before
anything runs, an output that resolves to an input (the same path, a link, another name
of the same file, a fixed-name file of an output directory), and `bench.core.filenames`
refuses a file named from data that would be one. Each case leaves every input's bytes
as they were."""

from __future__ import annotations

import argparse
import json
import os

import pytest
from cli_errors import one_line

from bench.cli import build_parser, main


def table(tmp_path, name="T.csv"):
    t = tmp_path / name
    t.write_text("time,set_point,load\n" + "".join(f"{k * 0.01!r},{k!r},40\n" for k in range(6)))
    m = tmp_path / "map.csv"
    m.write_text("signal,column,unit,scale\nt_s,time,s,1\nsetpoint_position_m,set_point,mm,1\n")
    return t, m


def snapshot(*paths):
    return {str(p): p.read_bytes() for p in paths}


def test_every_command_declares_its_files():
    """The check runs for every command: each one is in the table."""
    from bench.cli.outputs import IO_TABLE
    leaves = []

    def walk(parser, words):
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            leaves.append(" ".join(words))
            return
        for name, sp in subs[0].choices.items():
            walk(sp, [*words, name])
    walk(build_parser(None), [])
    assert sorted(set(leaves) - set(IO_TABLE)) == []
    dests = {}
    for name, sp in build_parser(None)._subparsers._group_actions[0].choices.items():
        dests[name] = {a.dest for a in sp._actions}
    for name, io in IO_TABLE.items():
        top = name.split()[0]
        if " " not in name:
            assert set(io.inputs) | set(io.files) | set(io.dirs) <= dests[top], name


def test_import_over_its_own_table_or_map_is_refused(tmp_path, capsys):
    """`bench import T.csv -o T.csv` and `-o` equal to the map overwrote them."""
    t, m = table(tmp_path)
    before = snapshot(t, m)
    rc = main(["import", str(t), "--map", str(m), "-o", str(t)])
    one_line(capsys, rc, "-o", "input TABLE")
    rc = main(["import", str(t), "--map", str(m), "-o", str(m)])
    one_line(capsys, rc, "-o", "input --map")
    os.link(t, tmp_path / "hard.csv")
    os.symlink(t, tmp_path / "soft.csv")
    for other in ("hard.csv", "soft.csv"):
        rc = main(["import", str(t), "--map", str(m), "-o", str(tmp_path / other)])
        one_line(capsys, rc, "-o", "input TABLE")
    assert snapshot(t, m) == before


def test_a_split_over_a_table_named_like_a_split_trace_is_refused(tmp_path, capsys):
    """`--split-by load --format csv -o .` over a table named `load=40.csv` overwrote it."""
    t, m = table(tmp_path, "load=40.csv")
    before = snapshot(t, m)
    rc = main(["import", str(t), "--map", str(m), "--split-by", "load", "--format", "csv",
               "-o", str(tmp_path)])
    one_line(capsys, rc, "load=40.csv", "is an input of this command")
    assert snapshot(t, m) == before
    assert sorted(os.listdir(tmp_path)) == ["load=40.csv", "map.csv"]


def test_json_outputs_over_their_inputs_are_refused_before_the_work(tmp_path, capsys):
    """`calibrate -o` equal to --actuator, `gap --json` equal to --nominal, `hums prognose
    --json` equal to the trends or the calibration were written over after the work."""
    log = tmp_path / "run.log"
    log.write_text("(1.000000) can0 080#01\n")
    desc = tmp_path / "actuator.json"
    desc.write_text(json.dumps({"name": "x"}))
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    trends = tmp_path / "trends.csv"
    trends.write_text("t,ci\n")
    before = snapshot(log, desc, cal, trends)
    cases = [(["calibrate", str(log), "--actuator", str(desc), "-o", str(desc)], "--actuator"),
             (["calibrate", str(log), "--nominal", str(cal)], None),
             (["gap", str(log), "--nominal", str(cal), "--json", str(cal)], "--nominal"),
             (["hums", "prognose", "--trends", str(trends), "--calibration", str(cal),
               "--json", str(cal)], "--calibration"),
             (["hums", "prognose", "--trends", str(trends), "--calibration", str(cal),
               "--json", str(trends)], "--trends"),
             (["usage", str(log), "--json", str(log)], "input LOG_OR_TRACE")]
    cases[1][0].extend(["-o", str(cal)])
    for argv, word in cases:
        rc = main(argv)
        one_line(capsys, rc, "that is the input", word or "--nominal")
    assert snapshot(log, desc, cal, trends) == before


def test_an_export_into_the_folder_of_a_store_named_runs_parquet_is_refused(tmp_path, capsys):
    """`fleet export` of a store named runs.parquet into its own folder: BinderException."""
    from bench.fleet.store import Store
    db = tmp_path / "runs.parquet"
    Store(db).close()
    before = snapshot(db)
    rc = main(["fleet", "export", "--db", str(db), "--out", str(tmp_path)])
    one_line(capsys, rc, "runs.parquet", "that is the input --db")
    with Store(db, read_only=True) as st, pytest.raises(Exception, match="over the store"):
        st.export(tmp_path)
    assert snapshot(db) == before


def test_two_outputs_at_one_path_are_refused(tmp_path, capsys):
    rc = main(["hums", "campaign", "--usage", "--json", str(tmp_path / "x.json"),
               "--calibration-out",
               str(tmp_path / "x.json")])
    one_line(capsys, rc, "are one file")


def test_every_error_is_one_line(tmp_path, capsys):
    """argparse's usage errors printed the usage text, then the error; a newline in a
    path gave an error of two lines; a file name too long for the system was exit 1
    "OSError"; an npz whose metadata is no JSON object an AttributeError."""
    import numpy as np
    with pytest.raises(SystemExit) as ex:
        main(["decode", "x.log", "--period", "abc"])
    assert ex.value.code == 2
    one_line(capsys, 2, "bench decode: argument --period: invalid float value: 'abc'")
    one_line(capsys, main(["fleet", "status", "--db", "a\nb"]), "a\\nb")
    one_line(capsys, main(["fleet", "status", "--db", "x" * 300]), "File name too long")
    np.savez(tmp_path / "t.npz", __meta__="[1, 2]", t_s=np.arange(3.0))
    one_line(capsys, main(["usage", str(tmp_path / "t.npz")]),
             "its metadata is not a JSON object but list")
