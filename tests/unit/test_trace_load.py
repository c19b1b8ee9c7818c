"""`Trace.load`: a trace file that is not one, or whose time is not finite and
increasing, or that holds an infinite value, is a one-line BenchError naming the file
(NaN, the missing-value marker, stays allowed)."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.signals.trace import Trace


def _trace(t, cur) -> Trace:
    return Trace({"t_s": np.asarray(t, float), "current_a": np.asarray(cur, float)})


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".parquet"])
def test_a_saved_trace_loads_back_with_its_nans(tmp_path, suffix):
    path = _trace([0, 0.1, 0.2], [1.0, np.nan, 2.0]).save(tmp_path / f"t{suffix}")
    tr = Trace.load(path)
    np.testing.assert_array_equal(tr["current_a"], [1.0, np.nan, 2.0])


@pytest.mark.parametrize("suffix, where", [(".npz", "row 3"), (".csv", "line 4"),
                                           (".parquet", "row 3")])
@pytest.mark.parametrize("t, cur, msg", [
    ([0, 0.1, 0.05], [1, 2, 3], r"the time t_s does not increase \(0.1 s, then 0.05 s\)"),
    ([0, 0.1, 0.1], [1, 2, 3], "the time t_s does not increase"),
    ([0, 0.1, np.nan], [1, 2, 3], r"the time t_s is nan \(1 row\(s\) without a finite"),
    ([0, 0.1, 0.2], [1, 2, np.inf], "column 'current_a' holds an infinite value"),
])
def test_a_bad_time_or_an_infinite_value_is_refused(tmp_path, suffix, where, t, cur, msg):
    path = _trace(t, cur).save(tmp_path / f"t{suffix}")
    with pytest.raises(BenchError, match=f"t{suffix} {where}: {msg}"):
        Trace.load(path)


@pytest.mark.parametrize("name, data, msg", [
    ("t.npz", b"not a zip", r"t.npz: not a readable .npz table \(not a zip archive"),
    ("t.parquet", b"not parquet", r"t.parquet: cannot read Parquet \(ArrowInvalid"),
    ("t.csv", b"t_s,x\n0,\xe9\n", r"t.csv: not UTF-8 text \(byte 0xe9 at offset 8\)"),
])
def test_an_unreadable_trace_file_is_one_line(tmp_path, name, data, msg):
    (tmp_path / name).write_bytes(data)
    with pytest.raises(BenchError, match=msg):
        Trace.load(tmp_path / name)


def test_a_rig_table_given_as_a_trace_points_to_bench_import(tmp_path):
    (tmp_path / "rig.csv").write_text("set_point,profile,time\n20.96,trap,0\n")
    with pytest.raises(BenchError, match=r"rig.csv line 2: column 'profile' is not a number: "
                                         r"'trap'; .*`bench import TABLE --map MAP`"):
        Trace.load(tmp_path / "rig.csv")
    (tmp_path / "num.csv").write_text("set_point,time\n20.96,0\n21.92,0.04\n")
    with pytest.raises(BenchError, match=r"num.csv: no time column t_s \(it has: set_point, "
                                         r"time\); .*`bench import TABLE --map MAP`"):
        Trace.load(tmp_path / "num.csv")


@pytest.mark.parametrize("columns, msg", [
    ({"t_s": np.float64(3.0), "current_a": np.float64(1.0)},
     r"t.npz: trace column 't_s' is 0-D \(shape \(\)\), not one value per row"),
    ({"t_s": np.array(["a", "b"]), "current_a": np.array([1.0, 2.0])},
     r"t.npz: trace column 't_s' is not a column of numbers \(could not convert"),
    ({"t_s": np.zeros((3, 3))}, r"t.npz: trace column 't_s' is 2-D \(shape \(3, 3\)\)"),
    ({"t_s": np.arange(3.0), "position_m": np.ones(3) * 1j},
     "t.npz: trace column 'position_m' holds complex numbers, not real ones"),
    ({"t_s": np.array([]), "position_m": np.array([])}, "t.npz: the trace has no rows"),
])
def test_an_npz_whose_columns_are_not_a_trace_is_one_line(tmp_path, columns, msg):
    """Found by fuzzing: a single value or text in an .npz was an exit 1
    (TypeError: len() of unsized object / ValueError) in usage, gap, calibrate and hums
    report; complex numbers lost their imaginary part and an empty trace gave `bench
    usage` a run of 0 s, both with exit 0."""
    np.savez(tmp_path / "t.npz", **columns)
    with pytest.raises(BenchError, match=msg):
        Trace.load(tmp_path / "t.npz")


def test_a_header_only_csv_trace_has_no_rows(tmp_path):
    (tmp_path / "t.csv").write_text("t_s,position_m\n")
    with pytest.raises(BenchError, match="t.csv: the table has a header but no rows"):
        Trace.load(tmp_path / "t.csv")
