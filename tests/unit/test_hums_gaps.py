"""The HUMS report on damaged traces: short gaps (lost SYNCs, a
missing frame) are bridged and counted, longer ones make the indexes that need the signal
"not available" with the reason, and no verdict is given without the index it rests on
(UNKNOWN, and `bench hums report` exits non-zero)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench.hums import report as HR
from bench.profiles.catalog import make_profile
from bench.signals.trace import MODE_IDLE, Trace
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


@pytest.fixture(scope="module")
def healthy() -> Trace:
    p = PlantParams().with_dict({"sensors.noise": True, "sensors.noise_seed": 6})
    return simulate(make_profile("sine", duration_s=2.0), p).measured()


@pytest.fixture(scope="module")
def intact(healthy):
    return HR.analyse(_copy(healthy), "intact", rul=False)


def _copy(tr: Trace, rows: slice = slice(None)) -> Trace:
    return Trace({k: v[rows].copy() for k, v in tr.columns.items()}, dict(tr.meta))


def _blank(tr: Trace, cols, lo: int, n: int) -> Trace:
    out = _copy(tr)
    for c in cols:
        out.columns[c][lo:lo + n] = np.nan
    return out


def test_short_gaps_are_bridged_counted_and_change_nothing_that_matters(healthy, intact):
    tr = _blank(healthy, ["current_a"], 700, 1)                  # one TPDO1 missing
    tr = _blank(tr, ["position_m"], 1200, 4)                      # four TPDO3 missing
    tr = _blank(tr, [c for c in tr.columns if c != "t_s"], 1500, 1)   # one lost SYNC
    a = HR.analyse(tr, "gaps", rul=False)
    assert a.bridged == {"setpoint_position_m": 1, "setpoint_speed_rad_s": 1, "mode": 1,
                         "current_demand_a": 1, "current_a": 2, "motor_speed_rad_s": 1,
                         "motor_angle_rad": 1, "position_m": 5, "load_force_n": 1}
    assert not a.indexes.unavailable
    assert a.verdict.name == intact.verdict.name == "HEALTHY"
    assert a.indexes.ci == pytest.approx(intact.indexes.ci, abs=2e-3)
    assert a.indexes.ci_harmonic == pytest.approx(intact.indexes.ci_harmonic, abs=2e-3)
    assert a.indexes.cp == pytest.approx(intact.indexes.cp, abs=1e-4)
    assert a.indexes.lost_motion_m == pytest.approx(intact.indexes.lost_motion_m, abs=0.2e-6)
    assert any(n.startswith("short gaps bridged by interpolation: setpoint_position_m 1 "
                            "sample,") and "position_m 5 samples" in n for n in a.notes), a.notes


def test_a_long_gap_makes_the_indexes_that_need_it_unavailable(healthy, intact):
    a = HR.analyse(_blank(healthy, ["current_a"], 500, 120), "long", rul=False)
    ix = a.indexes
    assert math.isnan(ix.ci) and math.isnan(ix.ci_harmonic) and math.isnan(ix.peak_ratio)
    assert ix.unavailable["ci"].startswith("not available: 120 samples missing in current_a")
    assert "longest gap 120 samples at t = 0.500 s" in ix.unavailable["ci"]
    assert ix.cp == pytest.approx(intact.indexes.cp, abs=1e-9)        # the LVDT is intact
    assert math.isfinite(ix.lost_motion_m)
    assert a.verdict.name == "UNKNOWN"
    assert a.reasons[0].startswith("Ci not available: 120 samples missing in current_a")


@pytest.mark.parametrize("rows", [1, 3, 99])
def test_no_verdict_on_a_log_too_short_for_the_index(healthy, rows):
    a = HR.analyse(_copy(healthy, slice(0, rows)), "short", rul=False)
    assert a.verdict.name == "UNKNOWN"
    word = "row" if rows == 1 else "rows"
    assert a.reasons[0] == f"Ci not available ({rows} {word}, at least 100 needed)"


def test_no_verdict_when_nothing_was_commanded(healthy):
    tr = _copy(healthy)
    tr.columns["mode"][:] = MODE_IDLE
    a = HR.analyse(tr, "idle", rul=False)
    assert a.verdict.name == "UNKNOWN"
    assert "nothing was commanded" in a.reasons[0]


def test_report_exits_non_zero_when_a_log_has_no_verdict(healthy, tmp_path, capsys):
    from bench.cli import main
    _copy(healthy).save(tmp_path / "good.npz")
    _copy(healthy, slice(0, 3)).save(tmp_path / "three.npz")
    rc = main(["hums", "report", str(tmp_path / "good.npz"), str(tmp_path / "three.npz"),
               "--no-rul", "--out", str(tmp_path / "rep")])
    out, err = capsys.readouterr()
    assert rc == 3
    assert "three.npz: UNKNOWN; Ci not available (3 rows, at least 100 needed)" in out
    assert "good.npz: HEALTHY" in out
    assert err.startswith("error: no verdict for three.npz") and len(err.splitlines()) == 1
    js = json.loads((tmp_path / "rep" / "indexes.json").read_text())
    assert [x["verdict"] for x in js] == ["HEALTHY", "UNKNOWN"]
    assert "UNKNOWN" in (tmp_path / "rep" / "report.html").read_text()
