"""Units and types from tables, one rule per case (`bench.signals.tables`, `bench.signals.trace`): a
Parquet timestamp column is time in seconds; a value that overflows once scaled is
refused; a UTF-8 byte-order mark is dropped; a header name given twice is refused; each
message names the column and the line. A big table is read as a stream."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from bench import BenchError
from bench.gap.importer import import_table, read_map
from bench.signals.trace import Trace

MAP = [{"signal": "t_s", "column": "time", "unit": "s"},
       {"signal": "setpoint_position_m", "column": "set_point", "unit": "mm"},
       {"signal": "load_force_n", "column": "load", "unit": "kgf"}]


def _map(tmp_path, entries=MAP):
    (tmp_path / "m.json").write_text(json.dumps(entries))
    return read_map(tmp_path / "m.json")


def _csv(tmp_path, header="time,set_point,load", rows=None, bom=False):
    rows = rows or [f"{k * 0.01!r},{1.0 + k!r},{40 + k}" for k in range(6)]
    text = header + "\n" + "\n".join(rows) + "\n"
    path = tmp_path / "t.csv"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode())
    return path


def test_a_parquet_timestamp_column_is_time_in_seconds(tmp_path):
    """It was read as seconds x 10^6 (microseconds taken for seconds)."""
    t = np.datetime64("2026-01-05T08:00:00", "us") + np.arange(6) * np.timedelta64(10, "ms")
    table = pa.table({"time": pa.array(t, pa.timestamp("us")),
                      "set_point": np.arange(6.0), "load": np.full(6, 40.0)})
    pq.write_table(table, tmp_path / "t.parquet")
    tr = import_table(tmp_path / "t.parquet", _map(tmp_path))
    # float64 epoch seconds resolve 0.24 us in 2026
    np.testing.assert_allclose(tr.t, np.arange(6) * 0.01, atol=5e-7)
    assert tr.meta["sample_period_s"] == pytest.approx(0.01)
    assert tr.meta["time_offset_s"] == pytest.approx(1767600000.0, abs=1e-6)
    with pytest.raises(BenchError, match="column 'time' holds timestamps .* map it with unit "
                                         "s and scale 1 \\(not 'ms'"):
        import_table(tmp_path / "t.parquet", _map(tmp_path, [{**MAP[0], "unit": "ms"},
                                                             *MAP[1:]]))
    with pytest.raises(BenchError, match="column 'time' holds timestamps .*not values of "
                                         "setpoint_position_m"):
        import_table(tmp_path / "t.parquet", _map(tmp_path, [
            {"signal": "t_s", "column": "load", "unit": "s"},
            {"signal": "setpoint_position_m", "column": "time", "unit": "mm"}]))


def test_a_trace_whose_parquet_time_is_a_timestamp_is_read_in_seconds(tmp_path):
    t = np.datetime64("2026-01-05T08:00:00", "ns") + np.arange(5) * np.timedelta64(1, "ms")
    pq.write_table(pa.table({"t_s": pa.array(t, pa.timestamp("ns", tz="UTC")),
                             "position_m": np.zeros(5)}), tmp_path / "tr.parquet")
    tr = Trace.load(tmp_path / "tr.parquet")
    assert tr.t[0] == pytest.approx(1767600000.0, abs=1e-6)
    assert tr.dt == pytest.approx(1e-3, abs=5e-7)


def test_a_value_that_overflows_once_scaled_is_refused_naming_column_and_line(tmp_path):
    """1e308 kgf was stored as inf with exit 0."""
    rows = [f"{k * 0.01!r},{1.0 + k!r},{'1e308' if k == 3 else 40}" for k in range(6)]
    path = _csv(tmp_path, rows=rows)
    with pytest.raises(BenchError, match=r"t.csv line 5: column 'load' \(load_force_n\): "
                                         r"1e\+308 kgf x 1 is beyond the range"):
        import_table(path, _map(tmp_path))


def test_a_utf8_byte_order_mark_before_the_header_is_dropped(tmp_path):
    """A BOM gave "no column 'set_point'", the BOM invisible in the message... for the
    first column, time."""
    path = _csv(tmp_path, bom=True)
    tr = import_table(path, _map(tmp_path))
    assert len(tr) == 6
    Trace({"t_s": np.arange(3.0), "x": np.ones(3)}).save(tmp_path / "tr.csv")
    data = (tmp_path / "tr.csv").read_bytes()
    (tmp_path / "tr.csv").write_bytes(b"\xef\xbb\xbf" + data)
    assert len(Trace.load(tmp_path / "tr.csv")) == 3
    (tmp_path / "m.json").write_bytes(b"\xef\xbb\xbf" + json.dumps(MAP).encode())
    assert len(read_map(tmp_path / "m.json")) == 3


def test_a_header_name_given_twice_is_refused_naming_it(tmp_path):
    """A duplicated header name blamed the values."""
    path = _csv(tmp_path, header="time,load,load",
                rows=[f"{k * 0.01!r},{k},{k}" for k in range(6)])
    with pytest.raises(BenchError, match=r"t.csv line 1: column 'load' appears 2 times in "
                                         r"the header \(columns 2 and 3\)|columns 2, 3"):
        import_table(path, _map(tmp_path, [MAP[0], {**MAP[2]}]))
    (tmp_path / "tr.csv").write_text("t_s,x,x\n0,1,2\n1,1,2\n")
    with pytest.raises(BenchError, match="column 'x' appears 2 times"):
        Trace.load(tmp_path / "tr.csv")
    pq.write_table(pa.Table.from_arrays([pa.array([0.0, 1.0]), pa.array([1.0, 2.0]),
                                         pa.array([3.0, 4.0])], names=["t_s", "x", "x"]),
                   tmp_path / "d.parquet")
    with pytest.raises(BenchError, match="column 'x' appears 2 times"):
        Trace.load(tmp_path / "d.parquet")


def test_a_control_character_in_a_column_name_is_shown(tmp_path):
    path = _csv(tmp_path, header="time,set\x00point,load")
    with pytest.raises(BenchError, match=r"'set\\x00point'"):
        import_table(path, _map(tmp_path))


def test_a_big_table_is_read_as_a_stream_within_its_columns_memory(tmp_path):
    """A 200 MB, 20 M-row CSV peaked at 5.1 GB (the text, then a list of rows): the
    columns now grow as arrays, 8 bytes a cell, with a bar for big files; here 20,000
    rows of 4 columns and the peak of the reading step's allocations."""
    import tracemalloc

    from bench.signals.tables import read_rows
    n = 20_000
    path = tmp_path / "big.csv"
    with path.open("w") as fh:
        fh.write("time,set_point,load,other\n")
        for k in range(n):
            fh.write(f"{k * 1e-3:.3f},{k % 100},40,7\n")
    tracemalloc.start()
    cols, rows = read_rows(path, ["time", "set_point", "load"])
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert len(cols["time"]) == n and int(rows.numbers[-1]) == n + 1
    # 3 columns + line numbers = 32 bytes a row; array growth and one line's objects
    assert peak < 2.5 * 32 * n, peak
    from bench.signals import tables as T
    T_limit = T.max_rows

    def small(n_columns, available=None):
        return 1000
    T.max_rows = small
    try:
        with pytest.raises(BenchError, match="more than 1000 rows of the 3 columns read "
                                             ".*split the table"):
            read_rows(path, ["time", "set_point", "load"])
    finally:
        T.max_rows = T_limit
