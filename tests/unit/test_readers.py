"""The one table reader and the one log loader, each chosen by suffix through a registry
(`bench.signals.tables.TABLE_READERS`, `bench.bus.logs.LOG_READERS`), and the calibration kinds."""

from __future__ import annotations

import json
import lzma

import numpy as np
import pytest

from bench import BenchError
from bench.bus.logs import LOG_READERS, load_trace
from bench.bus.logwrite import LOG_FORMATS
from bench.gap.inputs import Calibration, nominal_params, read_nominal
from bench.rig.riggap import is_rig_doc
from bench.signals.tables import TABLE_READERS, TRACE_FORMATS, read_table, table_suffix
from bench.signals.trace import Trace


def _one_line(exc: pytest.ExceptionInfo[BenchError]) -> str:
    text = str(exc.value)
    assert "\n" not in text
    return text


@pytest.mark.parametrize(("read", "name", "content", "kind", "known"), [
    (read_table, "t.xlsx", "a,b\n1,2\n", "table", TABLE_READERS),
    (load_trace, "run.mdf", "x", "log", LOG_READERS),
])
def test_an_unknown_suffix_is_one_line_naming_the_known_ones(tmp_path, read, name, content,
                                                            kind, known):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(BenchError) as exc:
        read(path)
    text = _one_line(exc)
    assert f"unknown {kind} format '{path.suffix}'" in text
    assert all(s in text for s in known), text


def test_an_unknown_table_suffix_names_the_formats_the_caller_reads(tmp_path):
    (tmp_path / "t.xlsx").write_text("a,b\n1,2\n")
    with pytest.raises(BenchError) as exc:
        read_table(tmp_path / "t.xlsx", formats=(".csv", ".parquet"))
    assert "(use .csv, .parquet;" in _one_line(exc)


def test_the_reader_is_the_suffix_s_under_a_compression_suffix(tmp_path):
    assert table_suffix("spalling1.CSV.xz") == ".csv"
    assert table_suffix("t.parquet") == ".parquet"
    text = "time,set_point,profile\n0,1.5,trap\n0.04,,trap\n"
    (tmp_path / "t.csv").write_text(text)
    (tmp_path / "t.csv.xz").write_bytes(lzma.compress(text.encode()))
    for name in ("t.csv", "t.csv.xz"):
        tab = read_table(tmp_path / name, text=True)
        assert list(tab.columns) == ["time", "set_point"]
        np.testing.assert_array_equal(tab.columns["set_point"], [1.5, np.nan])
        assert list(tab.text["profile"]) == ["trap", "trap"]
        assert list(tab.rows.numbers) == [2, 3]


def test_every_trace_format_reads_back_through_the_registry(tmp_path):
    tr = Trace({"t_s": np.arange(4) * 1e-3, "position_m": np.array([0.0, 1e-4, 2e-4, 3e-4])},
               {"scenario": "x"})
    for suffix in TRACE_FORMATS:
        path = tr.save(tmp_path / f"t{suffix}")
        back = load_trace(path)
        np.testing.assert_array_equal(back["position_m"], tr["position_m"])
        assert back.meta["source"] == str(path)


def test_the_log_registry_covers_the_bus_logs_and_the_traces():
    assert set(LOG_READERS) == set(LOG_FORMATS) | set(TRACE_FORMATS)


def test_measured_drops_the_truth_and_keeps_what_a_log_carries(tmp_path):
    tr = Trace({"t_s": np.arange(3) * 1e-3, "position_m": np.zeros(3),
                "true_position_m": np.zeros(3)},
               {"fundamental_hz": 2.0, "sync_gaps": 1, "scenario": "sim"})
    path = tr.save(tmp_path / "t.npz")
    out = load_trace(path, measured=True)
    assert "true_position_m" not in out and "position_m" in out
    assert out.meta == {"source": str(path), "sync_gaps": 1, "fundamental_hz": 2.0}


def test_a_calibration_says_its_kind_and_old_files_stay_readable(tmp_path):
    old_rig = {"model": "generic nut-level model (bench.sim.rigmodel)", "values": {}}
    old_plant = {"model": "plant", "params": {"effects.preload_n": 1000.0}}
    assert Calibration.of(old_rig).kind == "actuator" and is_rig_doc(old_rig)
    assert Calibration.of(old_plant).kind == "plant" and not is_rig_doc(old_plant)
    assert Calibration.of({"screw": {}}) is None               # a parameter file
    new = Calibration("plant", old_plant).to_dict()
    assert next(iter(new)) == "kind" and new["kind"] == "plant"
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(new))
    assert nominal_params(read_nominal(path), path).effects.preload_n == 1000.0
    path.write_text(json.dumps({**new, "kind": "fleet"}))
    with pytest.raises(BenchError) as exc:
        nominal_params(read_nominal(path), path)
    assert "unknown calibration kind 'fleet' (known: plant, actuator)" in _one_line(exc)
