"""`bench import`: tables at fixed or varying rates with a column map -> SYNC-rate trace."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench import BenchError
from bench.gap.importer import import_table, read_map


def write_table(path, t, cols: dict[str, np.ndarray]) -> None:
    names = ["time_ms", *cols]
    rows = [",".join(names)]
    for i in range(len(t)):
        rows.append(",".join([repr(float(t[i] * 1e3))] + [
            "" if not np.isfinite(cols[c][i]) else repr(float(cols[c][i])) for c in cols]))
    path.write_text("\n".join(rows) + "\n")


MAP = [{"signal": "t_s", "column": "time_ms", "unit": "ms"},
       {"signal": "position_m", "column": "lvdt", "unit": "mm", "scale": 1.0},
       {"signal": "motor_speed_rad_s", "column": "rpm", "unit": "rpm"},
       {"signal": "current_a", "column": "i_ma", "unit": "mA"},
       {"signal": "motor_angle_rad", "column": "ang_deg", "unit": "deg", "wrap": 360},
       {"signal": "mode", "column": "mode", "unit": "-"},
       {"signal": "setpoint_position_m", "column": "sp", "unit": "um", "scale": -1.0}]


@pytest.fixture
def table(tmp_path):
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.2e-3, 1.8e-3, 3000))     # varying rate, ~1 kHz
    ang = np.mod(np.degrees(3.0 * t), 360.0)              # wraps every 2.1 s
    cols = {"lvdt": 2.0 * np.sin(t), "rpm": 60.0 * np.ones_like(t), "i_ma": 500 * t,
            "ang_deg": ang, "mode": (t > 1.0).astype(float), "sp": -1000 * t}
    cols["i_ma"][::7] = np.nan                             # a channel logged slower
    write_table(tmp_path / "rig.csv", t, cols)
    (tmp_path / "map.json").write_text(json.dumps(MAP))
    return tmp_path, t


def test_import_resamples_and_converts_units(table):
    tmp, t = table
    tr = import_table(tmp / "rig.csv", read_map(tmp / "map.json"), 1e-3)
    assert tr.dt == pytest.approx(1e-3)
    ts = tr.t + tr.meta["time_offset_s"]
    np.testing.assert_allclose(tr["position_m"], 2e-3 * np.sin(ts), atol=2e-9)
    np.testing.assert_allclose(tr["motor_speed_rad_s"], 2 * math.pi, rtol=1e-12)
    np.testing.assert_allclose(tr["current_a"], 0.5 * ts, atol=1e-9)
    np.testing.assert_allclose(tr["motor_angle_rad"], 3.0 * ts, atol=1e-6)   # unwrapped
    np.testing.assert_allclose(tr["setpoint_position_m"], 1e-3 * ts, atol=1e-12)
    assert set(np.unique(tr["mode"])) == {0.0, 1.0}
    last = t[np.clip(np.searchsorted(t, ts + 1e-12, side="right") - 1, 0, None)]
    np.testing.assert_array_equal(tr["mode"], (last > 1.0).astype(float))  # previous value
    out = tr.save(tmp / "out.parquet")
    assert out.exists()


def test_csv_map_and_fixed_rate_without_time(tmp_path):
    (tmp_path / "t.csv").write_text("a;b\n" + "\n".join(f"{i};{2 * i}" for i in range(50)))
    (tmp_path / "m.csv").write_text("signal,column,unit,scale\nposition_m,a,mm,\n"
                                    "current_a,b,A,0.5\n")
    tr = import_table(tmp_path / "t.csv", read_map(tmp_path / "m.csv"), 1e-3,
                      source_rate_hz=500.0)
    np.testing.assert_allclose(tr["position_m"][:5], [0, 0.5e-3, 1e-3, 1.5e-3, 2e-3])
    np.testing.assert_allclose(tr["current_a"], tr["position_m"] * 1e3)


@pytest.mark.parametrize("entry, msg", [
    ({"signal": "positon_m", "column": "lvdt", "unit": "mm"}, "unknown bench signal 'positon_m'"),
    ({"signal": "position_m", "column": "lvdt", "unit": "furlong"},
     "unit 'furlong' is not a length unit for position_m"),
    ({"signal": "current_a", "column": "i_ma", "unit": "mA", "scale": "x"}, "scale of current_a"),
])
def test_bad_map_entries_are_clear(tmp_path, entry, msg):
    (tmp_path / "m.json").write_text(json.dumps([entry]))
    with pytest.raises(BenchError, match=msg):
        read_map(tmp_path / "m.json")


def test_unknown_column_and_missing_time_are_clear(table):
    tmp, _ = table
    (tmp / "m2.json").write_text(json.dumps({"t_s": {"column": "time_ms", "unit": "ms"},
                                             "position_m": {"column": "LVDT", "unit": "mm"}}))
    with pytest.raises(BenchError, match=r"no column\(s\) 'LVDT' \(the table has: time_ms"):
        import_table(tmp / "rig.csv", read_map(tmp / "m2.json"))
    (tmp / "m3.json").write_text(json.dumps({"position_m": {"column": "lvdt", "unit": "mm"}}))
    with pytest.raises(BenchError, match="no time signal t_s"):
        import_table(tmp / "rig.csv", read_map(tmp / "m3.json"))


def test_time_going_backwards_is_reported(tmp_path):
    (tmp_path / "t.csv").write_text("t,x\n0,1\n0.002,2\n0.001,3\n0.003,4\n")
    (tmp_path / "m.json").write_text(json.dumps({"t_s": {"column": "t", "unit": "s"},
                                                 "position_m": {"column": "x", "unit": "m"}}))
    with pytest.raises(BenchError, match="t.csv: time goes backwards.*line 4"):
        import_table(tmp_path / "t.csv", read_map(tmp_path / "m.json"))


TX = {"t_s": {"column": "t", "unit": "s"}, "current_a": {"column": "i", "unit": "A"}}


def _tx(tmp_path, body: str, name: str = "t.csv"):
    """A two-column table t,i (body: its data lines) and the map of both."""
    (tmp_path / name).write_text("t,i\n" + body)
    (tmp_path / "m.json").write_text(json.dumps(TX))
    return tmp_path / name, read_map(tmp_path / "m.json")


def test_an_infinite_value_is_refused_naming_line_and_column(tmp_path):
    table, mapping = _tx(tmp_path, "0,1\n0.1,2\n0.2,inf\n0.3,4\n")
    with pytest.raises(BenchError, match=r"t.csv line 4: column 'i' holds an infinite value"):
        import_table(table, mapping)
    table, mapping = _tx(tmp_path, "0,1\n-inf,2\n0.2,3\n")
    with pytest.raises(BenchError, match=r"t.csv line 3: column 't' holds an infinite value"):
        import_table(table, mapping)


def test_an_infinite_value_in_parquet_is_refused_naming_the_row(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    pq.write_table(pa.table({"t": [0.0, 0.1, 0.2], "i": [1.0, math.inf, 2.0]}),
                   tmp_path / "t.parquet")
    (tmp_path / "m.json").write_text(json.dumps(TX))
    with pytest.raises(BenchError, match=r"t.parquet row 2: column 'i' holds an infinite"):
        import_table(tmp_path / "t.parquet", read_map(tmp_path / "m.json"))


@pytest.mark.parametrize("rows, message", [
    ("0,1\n0.1,2\n,3\n0.3,4\n", r"1 row\(s\) without a time in column 't' \(line 4\)"),
    ("0,1\n0.1,2\n0.1,5\n0.2,3\n",
     r"t.csv lines 3 and 4: the same time \(0.1 s\) with different values in column 'i'"),
], ids=["a row without a time", "a repeated time with another value"])
def test_a_row_without_a_time_or_a_repeated_time_is_refused_not_dropped(tmp_path, rows,
                                                                         message):
    table, mapping = _tx(tmp_path, rows)
    for sync in (None, 0.05):
        with pytest.raises(BenchError, match=message):
            import_table(table, mapping, sync)


def test_a_repeated_row_is_dropped_and_a_blank_filled_from_its_twin(tmp_path):
    table, mapping = _tx(tmp_path, "0,1\n0.1,2\n0.1,2\n0.2,\n0.2,3\n0.3,4\n")
    tr = import_table(table, mapping)
    np.testing.assert_allclose(tr.t, [0, 0.1, 0.2, 0.3])
    np.testing.assert_allclose(tr["current_a"], [1, 2, 3, 4])     # nothing lost


def test_a_constant_time_column_is_named(tmp_path):
    table, mapping = _tx(tmp_path, "0,1\n0,2\n0,3\n")
    with pytest.raises(BenchError, match="every row has the same time in column 't' "
                                         r"\(0 s\): the time column must increase"):
        import_table(table, mapping)


@pytest.mark.parametrize("name, data, msg", [
    ("t.csv.xz", b"not xz at all", r"t.csv.xz: cannot decompress \(LZMAError"),
    ("t.csv.gz", b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xffgarbage!!", "t.csv.gz: cannot decompress"),
    ("t.csv.bz2", b"BZh9garbage", "t.csv.bz2: cannot decompress"),
    ("t.csv", b"\xfd7zXZ\x00\x00binary", r"t.csv: not UTF-8 text \(byte 0xfd at offset 0\)"),
    ("t.csv", "t,i\n0,\xe9\n".encode("latin-1"), r"not UTF-8 text \(byte 0xe9 at offset 6\)"),
])
def test_a_corrupt_or_binary_table_is_one_line(tmp_path, name, data, msg):
    (tmp_path / name).write_bytes(data)
    (tmp_path / "m.json").write_text(json.dumps(TX))
    with pytest.raises(BenchError, match=msg):
        import_table(tmp_path / name, read_map(tmp_path / "m.json"))


def test_a_directory_as_table_or_map_is_one_line(tmp_path):
    (tmp_path / "d.csv").mkdir()
    (tmp_path / "d.json").mkdir()
    (tmp_path / "m.json").write_text(json.dumps(TX))
    with pytest.raises(BenchError, match="d.csv: is a directory, not a table file"):
        import_table(tmp_path / "d.csv", read_map(tmp_path / "m.json"))
    with pytest.raises(BenchError, match="d.json: is a directory, not a map file"):
        read_map(tmp_path / "d.json")


def test_a_fixed_rate_beside_a_time_column_is_refused(tmp_path):
    """--source-rate was ignored where the map gives t_s: the user's rate had no effect."""
    (tmp_path / "t.csv").write_text("t,a\n" + "\n".join(f"{i * 0.01},{i}" for i in range(20)))
    (tmp_path / "m.csv").write_text("signal,column,unit,scale\nt_s,t,s,\nposition_m,a,mm,\n")
    with pytest.raises(BenchError, match="--source-rate is for a table without a time"):
        import_table(tmp_path / "t.csv", read_map(tmp_path / "m.csv"), None,
                     source_rate_hz=100.0)
