"""`bench import` of a rig's table holding many runs: split by key columns,
named after the keys, load in kgf, position from set-point minus error, and a 25 Hz table
kept at its own sample instants (nothing interpolated)."""

from __future__ import annotations

import json
import lzma

import numpy as np
import pytest

from bench import BenchError
from bench.cli import main
from bench.gap.importer import import_table, read_map, split_table
from bench.signals.trace import Trace

MAP = [{"signal": "t_s", "column": "time", "unit": "s"},
       {"signal": "setpoint_position_m", "column": "set_point", "unit": "mm"},
       {"signal": "position_m", "column": "set_point", "minus": "position_error",
        "unit": "mm"},
       {"signal": "current_a", "column": "current", "unit": "A"},
       {"signal": "load_force_n", "column": "load", "unit": "kgf"}]


def cranfield_like(path, n: int = 30, xz: bool = False) -> None:
    """A Cranfield-shaped table: 2 loads x 2 runs x 2 cycles, 25 Hz, time restarting at 0
    every cycle, a text column (profile) the map does not read."""
    rows = ["set_point,position_error,current,profile,load,run,fault_type,group,time"]
    group = 0
    for load in (20, -40):
        for run in (1, 2):
            for _ in range(2):
                group += 1
                for k in range(n):
                    sp = 20.0 + 0.96 * k
                    rows.append(f"{sp!r},{0.1 * group + 0.01 * k!r},{0.4 + 0.01 * k!r},trap,"
                                f"{load},{run},0,{group},{k * 0.04!r}")
    text = "\n".join(rows) + "\n"
    if xz:
        with lzma.open(path, "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)


def test_split_names_kgf_and_25hz_kept(tmp_path):
    cranfield_like(tmp_path / "t.csv")
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    parts = split_table(tmp_path / "t.csv", read_map(tmp_path / "m.json"),
                        ["load", "run", "group"])
    names = [n for n, _ in parts]
    assert names[:3] == ["load=20_run=1_group=1", "load=20_run=1_group=2",
                         "load=20_run=2_group=3"]
    assert names[-1] == "load=-40_run=2_group=8" and len(names) == 8
    tr = dict(parts)["load=-40_run=1_group=5"]
    assert len(tr) == 30                                        # no 1 kHz grid
    np.testing.assert_allclose(tr.t, np.arange(30) * 0.04, atol=1e-12)
    assert tr.meta["sample_period_s"] == pytest.approx(0.04)
    assert tr.meta["resampled"] is False
    assert tr.meta["split"] == {"load": -40.0, "run": 1.0, "group": 5.0}
    np.testing.assert_allclose(tr["load_force_n"], -40 * 9.80665)
    k = np.arange(30)
    np.testing.assert_allclose(tr["position_m"], (20.0 + 0.96 * k - 0.5 - 0.01 * k) * 1e-3,
                               rtol=1e-12)
    np.testing.assert_allclose(tr["setpoint_position_m"], (20.0 + 0.96 * k) * 1e-3)


def test_unsplit_many_runs_say_how_to_split(tmp_path):
    cranfield_like(tmp_path / "t.csv")
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    with pytest.raises(BenchError, match="time goes backwards.*--split-by"):
        import_table(tmp_path / "t.csv", read_map(tmp_path / "m.json"))


def test_cli_split_of_an_xz_table(tmp_path, capsys):
    cranfield_like(tmp_path / "t.csv.xz", xz=True)
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    assert main(["import", str(tmp_path / "t.csv.xz"), "--map", str(tmp_path / "m.json"),
                 "--split-by", "load,run,group", "--format", "npz", "-o", str(tmp_path / "runs")]) == 0
    files = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert len(files) == 8 and "load=20_run=2_group=4.npz" in files
    tr = Trace.load(tmp_path / "runs" / "load=20_run=2_group=4.npz")
    assert len(tr) == 30 and tr.dt == pytest.approx(0.04)
    out = capsys.readouterr().out
    assert "8 traces split by load, run, group; sample period(s) 40 ms" in out
    assert "as sampled, 25 Hz" in out


def test_cli_bad_split_column_is_one_line(tmp_path, capsys):
    cranfield_like(tmp_path / "t.csv")
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    assert main(["import", str(tmp_path / "t.csv"), "--map", str(tmp_path / "m.json"),
                 "--split-by", "load,cycle", "-o", str(tmp_path / "runs")]) != 0
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "'cycle'" in err and err.count("\n") == 1


def test_split_by_the_time_column_is_refused(tmp_path):
    cranfield_like(tmp_path / "t.csv")
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    with pytest.raises(BenchError, match="--split-by time: that is the table's time column"):
        split_table(tmp_path / "t.csv", read_map(tmp_path / "m.json"), ["load", "time"])


def test_split_rows_without_a_key_are_refused_not_dropped(tmp_path):
    cranfield_like(tmp_path / "t.csv")
    lines = (tmp_path / "t.csv").read_text().splitlines()
    for n in (5, 40):                                      # group blank, then nan
        f = lines[n - 1].split(",")
        f[7] = "" if n == 5 else "nan"
        lines[n - 1] = ",".join(f)
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    with pytest.raises(BenchError, match=r"t.csv: 2 row\(s\) without a value in the split "
                                         r"column\(s\) load, run, group \(lines 5, 40\)"):
        split_table(tmp_path / "t.csv", read_map(tmp_path / "m.json"), ["load", "run", "group"])


def test_cli_split_checks_the_output_directory_first(tmp_path, capsys, monkeypatch):
    cranfield_like(tmp_path / "t.csv")
    (tmp_path / "m.json").write_text(json.dumps(MAP))
    import bench.gap.importer as imp
    monkeypatch.setattr(imp, "split_table", lambda *a, **k: pytest.fail("split first"))
    out = tmp_path / "t.csv" / "runs"                       # under a file: cannot be made
    assert main(["import", str(tmp_path / "t.csv"), "--map", str(tmp_path / "m.json"),
                 "--split-by", "load,run,group", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == f"error: -o: cannot write into {out}: {out.parent} is not a directory\n"
