"""File names made from data (`bench.core.filenames`): every writer that names a file after a
value of the data keeps it inside the folder given, one bounded name, and distinct
values keep distinct files; logs given by path get distinct labels."""

from __future__ import annotations

import datetime as dt
import json
import os

import numpy as np
import pytest

from bench.cli import main
from bench.core.filenames import MAX_NAME_BYTES, distinct_labels, safe_name
from bench.signals.trace import Trace


def files_under(root) -> set[str]:
    return {os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs}


@pytest.mark.parametrize("text", ["../../x", "/etc/passwd", "a/b", "x\ny", "..", ".", "-rf",
                                  "", "\x00", "a" * 300, "ü" * 200, "EMA 7", "EMA/7"])
def test_a_safe_name_is_one_bounded_name(text):
    name = safe_name(text)
    assert name and "/" not in name and "\\" not in name and name not in (".", "..")
    assert name.isprintable() and not name.startswith((".", "-"))
    assert len(name.encode()) <= MAX_NAME_BYTES + 9


def test_a_plain_name_is_kept_and_distinct_names_stay_distinct():
    assert safe_name("load=40_run=1_group=51") == "load=40_run=1_group=51"
    assert safe_name("EMA-0001") == "EMA-0001"
    names = {safe_name(t) for t in ("EMA 7", "EMA/7", "EMA_7", "EMA\n7", "a" * 300, "a" * 301)}
    assert len(names) == 6


def test_distinct_labels_tell_logs_with_one_name_apart():
    assert distinct_labels(["a/run.log", "b/run.log"]) == ["a/run.log", "b/run.log"]
    assert distinct_labels(["x/a/run.log", "y/a/run.log", "z.log"]) == \
        ["x/a/run.log", "y/a/run.log", "z.log"]
    assert distinct_labels(["run.log", "run.log"]) == ["run.log", "run.log (2)"]


def _table(path, keys, key_col="load") -> None:
    rows = [f"time,set_point,{key_col}"]
    for key in keys:
        for k in range(5):
            rows.append(f"{k * 0.01!r},{1.0 + k!r},{key}")
    path.write_text("\n".join(rows) + "\n")


def _map(path) -> None:
    path.write_text(json.dumps([{"signal": "t_s", "column": "time", "unit": "s"},
                                {"signal": "setpoint_position_m", "column": "set_point",
                                 "unit": "mm"}]))


@pytest.mark.parametrize("column", ["../../x", "/tmp/abs"])
def test_split_keys_named_after_a_hostile_column_stay_inside_out(tmp_path, column, capsys):
    """A --split-by column named `../../x` or an absolute path wrote its traces outside -o."""
    work = tmp_path / "w"
    work.mkdir()
    _table(work / "t.csv", [1, 2], key_col=column)
    _map(work / "m.json")
    before = files_under(tmp_path)
    out = work / "o" / "p"
    key = column
    assert main(["import", str(work / "t.csv"), "--map", str(work / "m.json"), "--split-by",
                 key, "-o", str(out), "--format", "csv"]) == 0
    new = files_under(tmp_path) - before
    assert len(new) == 2 and all(p.startswith(os.path.join("w", "o", "p") + os.sep)
                                 for p in new), new
    assert "2 traces" in capsys.readouterr().out


def test_split_keys_that_differ_after_the_fourth_digit_get_two_files(tmp_path, capsys):
    """Keys 100.0001 and 100.0002 both wrote `load=100.parquet`; the import said 2 traces."""
    _table(tmp_path / "t.csv", ["100.0001", "100.0002"])
    _map(tmp_path / "m.json")
    assert main(["import", str(tmp_path / "t.csv"), "--map", str(tmp_path / "m.json"),
                 "--split-by", "load", "-o", str(tmp_path / "o")]) == 0
    assert sorted(os.listdir(tmp_path / "o")) == ["load=100.0001.parquet",
                                                  "load=100.0002.parquet"]
    assert "2 traces" in capsys.readouterr().out


def _usage_trace(path, serial: str) -> None:
    t = np.arange(400) * 1e-3
    x = 1e-3 * np.sin(2 * np.pi * 2 * t)
    Trace({"t_s": t, "position_m": x, "setpoint_position_m": x,
           "motor_angle_rad": x / 0.002 * 2 * np.pi, "load_force_n": 100 + 0 * t,
           "current_a": 0.5 + 0 * t}, {"actuator_serial": serial}).save(path)


@pytest.fixture
def quick_figures(monkeypatch):
    """The usage figures as placeholder files: what is tested is where they go."""
    import bench.usage.figure as F

    def save(s, title, path):
        path.write_bytes(b"png")
        return path
    monkeypatch.setattr(F, "save_usage_figure", save)


def test_usage_plots_named_after_a_serial_stay_inside_the_folder(tmp_path, capsys,
                                                                 quick_figures):
    """A serial `x/../../y` wrote outside --plot DIR, `a/b` crashed, 300 characters
    gave 'File name too long'."""
    logs = tmp_path / "in"
    logs.mkdir()
    serials = ["x/../../y", "a/b", "/abs/z", "s" * 300]
    for k, serial in enumerate(serials):
        _usage_trace(logs / f"run{k}.npz", serial)
    before = files_under(tmp_path)
    assert main(["usage", *(str(logs / f"run{k}.npz") for k in range(4)),
                 "--plot", str(tmp_path / "p" / "q")]) == 0
    new = files_under(tmp_path) - before
    assert len(new) == 8 and all(n.startswith(os.path.join("p", "q") + os.sep) for n in new)
    assert "wrote 8 figure(s)" in capsys.readouterr().out


def test_usage_of_two_logs_of_one_name_counts_and_labels_each(tmp_path, capsys,
                                                             quick_figures):
    """`bench usage a/run.log b/run.log --plot` wrote 2 figures and said 3."""
    for d, serial in (("a", "7"), ("b", "8")):
        (tmp_path / d).mkdir()
        _usage_trace(tmp_path / d / "run.npz", serial)
    assert main(["usage", str(tmp_path / "a" / "run.npz"), str(tmp_path / "b" / "run.npz"),
                 "--plot", str(tmp_path / "p")]) == 0
    out = capsys.readouterr().out
    assert len(os.listdir(tmp_path / "p")) == 4 and "wrote 4 figure(s)" in out
    assert "a/run.npz" in out and "b/run.npz" in out


def test_fleet_report_pages_of_ids_that_collapse_and_a_300_character_id(tmp_path,
                                                                        monkeypatch):
    """`EMA 7`, `EMA/7` and `EMA_7` all linked to one page (showing the HEALTHY one while
    a FAILURE actuator linked to it); a 300-character id: 'File name too long'."""
    import bench.fleet.report as R
    from bench.fleet.store import Store
    monkeypatch.setattr(R, "_actuator_figure", lambda st, sub, path: path.write_bytes(b"png"))
    monkeypatch.setattr(R, "_fleet_figure", lambda *a: a[-1].write_bytes(b"png"))
    t0 = dt.datetime(2026, 1, 5, 8, 0)
    ids = {"EMA 7": "HEALTHY", "EMA/7": "FAILURE", "EMA_7": "DEGRADED", "x" * 300: "HEALTHY",
           "../../evil": "HEALTHY"}
    rows = []
    for n, (ident, verdict) in enumerate(ids.items()):
        for k in range(3):
            rows.append({"digest": f"d{n}-{k}", "actuator_id": ident,
                         "run_time": t0 + dt.timedelta(days=k), "path": f"/l/{n}/{k}.log",
                         "bytes": 1, "rows": 2000, "duration_s": 2.0, "mode": 1,
                         "f0_hz": 2.0, "verdict": verdict, "level": 0, "reasons": "r",
                         "notes": "", "ci": 0.5 if verdict == "FAILURE" else 1.0,
                         "ci_harmonic": 1.0, "cp": 1.0})
    db = tmp_path / "f.duckdb"
    with Store(db) as st:
        st.write(rows)
    out = tmp_path / "r"
    assert main(["fleet", "report", "--db", str(db), "--out", str(out)]) == 0
    pages = sorted((out / "actuators").glob("*.html"))
    assert len(pages) == 5
    assert all(files_under(tmp_path / "r"))
    assert not (tmp_path / "evil.html").exists()
    index = (out / "index.html").read_text()
    import re
    from urllib.parse import unquote
    links = re.findall(r'href="actuators/([^"]+)"', index)
    assert len(set(links)) == 5
    for link in set(links):
        page = (out / "actuators" / unquote(link)).read_text()
        img = re.search(r'<img alt="trends" src="([^"]+)"', page).group(1)
        assert (out / "actuators" / unquote(img)).is_file()
    heads = {p: re.search(r"<h1>(.*?)</h1>", p.read_text()).group(1) for p in pages}
    level = {p: re.search(r'<p><span class="v (\w+)">', p.read_text()).group(1) for p in pages}
    failure = [p for p, v in level.items() if v == "FAILURE"]
    assert len(failure) == 1 and heads[failure[0]] == "EMA/7: health"
