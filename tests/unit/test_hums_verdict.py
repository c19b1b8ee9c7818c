"""One verdict: `bench.hums.verdict.judge` is the report's verdict and the live
watcher's level; mode-aware, UNKNOWN without the index it rests on."""

from __future__ import annotations

import math

from bench.core.verdict import Level, Verdict
from bench.hums.indexes import Indexes
from bench.hums.live import LiveHums, PeriodResult
from bench.hums.verdict import THESIS_MODEL, judge
from bench.signals.trace import MODE_IDLE, MODE_POSITION, MODE_SPEED


def ix(**kw) -> Indexes:
    return Indexes(0.0, 0.5, **kw)


def test_position_mode_rests_on_ci():
    assert judge(ix(ci=0.99, cp=1.0), MODE_POSITION).name == "HEALTHY"
    assert judge(ix(ci=0.90), MODE_POSITION).name == "DEGRADED"
    assert judge(ix(ci=0.70), MODE_POSITION).name == "WARNING"
    assert judge(ix(ci=0.40), MODE_POSITION).name == "FAILURE"
    # the harmonic Ci comes first when there is one
    assert judge(ix(ci=0.99, ci_harmonic=0.70), MODE_POSITION).name == "WARNING"


def test_no_index_no_verdict():
    v = judge(ix(cp=1.0), MODE_POSITION)                        # Ci NaN
    assert v.level == Level.UNKNOWN and v.reasons[0].startswith("Ci ")
    assert v.effect == "not judged" and v.reference == THESIS_MODEL
    v = judge(ix(ci=0.99), MODE_SPEED)                          # Cp NaN in speed mode
    assert v.level == Level.UNKNOWN and v.reasons[0].startswith("Cp ")
    assert judge(ix(ci=0.99, cp=1.0), MODE_IDLE).level == Level.UNKNOWN


def test_speed_mode_rests_on_cp_not_ci():
    assert judge(ix(ci=0.40, cp=1.0), MODE_SPEED).name == "HEALTHY"
    assert judge(ix(ci=0.99, cp=1.02), MODE_SPEED).name == "DEGRADED"


def test_lost_motion_counts():
    assert judge(ix(ci=0.99, lost_motion_m=20e-6, nominal_lost_motion_m=0.0),
                 MODE_POSITION).name == "DEGRADED"


def test_live_levels_name_the_verdicts():
    r = PeriodResult(1, 0, 0.0, ix(), Verdict.unknown(["nothing"]))
    assert r.row()["level"] == "UNKNOWN" and r.level == Level.UNKNOWN


def test_live_period_is_judged_by_the_report_verdict():
    """A period whose Ci is NaN is UNKNOWN live, as in the report (it was HEALTHY)."""
    hums = LiveHums(0.5)
    hums._new_run()
    # fabricated rows: a whole command period in position mode with no current signal
    rows = [{"t_s": k * hums.dt, "setpoint_position_m": 0.0, "setpoint_speed_rad_s": 0.0,
             "mode": float(MODE_POSITION), "current_demand_a": 0.0, "current_a": math.nan,
             "motor_speed_rad_s": 0.0, "motor_angle_rad": 0.0, "position_m": 0.0}
            for k in range(hums._online.m)]
    out = hums._push(rows)
    assert len(out) == 1
    assert out[0].level == judge(out[0].indexes, MODE_POSITION).level == Level.UNKNOWN


def test_watcher_prints_and_writes_the_same_ci():
    """`bench hums watch` prints the judged Ci, and its CSV's ``ci`` is that number; the
    broadband reading is ``ci_broadband`` (it printed ci_harmonic, and wrote the broadband
    value as ``ci``)."""
    from bench.hums.live import format_result
    r = PeriodResult(1, 3, 1.5, ix(ci=0.7398, ci_harmonic=0.753, cp=1.0),
                     Verdict(Level.WARNING, "Ci"))
    assert "Ci  0.753" in format_result(r) and format_result(r).endswith("WARNING")
    row = r.row()
    assert row["level"] == "WARNING"
    assert (row["ci"], row["ci_broadband"], row["ci_harmonic"]) == (0.753, 0.7398, 0.753)


def test_judged_ci_is_the_harmonic_reading_else_broadband():
    import numpy as np

    from bench.hums.verdict import index_record, judged_ci
    assert judged_ci(0.897, 1.004) == 1.004
    assert judged_ci(0.897, math.nan) == 0.897
    np.testing.assert_array_equal(judged_ci(np.array([0.9, 0.8]), np.array([1.0, np.nan])),
                                  [1.0, 0.8])
    rec = index_record(ix(ci=0.897, ci_harmonic=1.004))
    assert (rec["ci"], rec["ci_broadband"], rec["ci_harmonic"]) == (1.004, 0.897, 1.004)


def _fused(b_um: float, detected: bool = True):
    """A fused result whose last three periods read `b_um`, on a calibration whose sweep
    Ci falls 0.0046 per um (Ci 0.80 at 43.5 um, 0.56 at b_fail 90 um)."""
    import numpy as np

    from bench.hums import fusion as F
    b = [10.0 * k for k in range(11)]
    cal = F.Calibration(b, {}, [1 - 0.0046 * x for x in b], {}, {}, {}, warn_um=0.98,
                        floor_um=0.8, fail_um=90.0)
    est = np.full(6, b_um)
    fr = F.FusedResult(est, est, 1.5 if detected else math.nan, [])
    return fr, cal, np.arange(6) * 0.5


def test_fused_backlash_is_graded_on_the_ci_levels_scale():
    """The detection level (0.98 um, the fused predictor's warning) is not a level of wear:
    backlash above it is DEGRADED; WARNING and FAILURE come at the backlash where the
    calibration sweep's Ci reaches 0.80 and 0.56."""
    healthy = ix(ci=0.99, ci_harmonic=0.99)
    v = judge(healthy, MODE_POSITION, _fused(5.0))
    level, reasons = v.name, v.reasons
    assert level == "DEGRADED" and v.effect == "fused backlash", reasons
    assert "detection level 0.98 um" in reasons[-1] and "warning backlash 43.5 um" in reasons[-1]
    assert judge(healthy, MODE_POSITION, _fused(50.0)).name == "WARNING"
    v = judge(healthy, MODE_POSITION, _fused(95.0))
    level, reasons = v.name, v.reasons
    assert level == "FAILURE" and "failure backlash 90.0 um" in reasons[-1]
    v = judge(healthy, MODE_POSITION, _fused(0.1, detected=False))
    level, reasons = v.name, v.reasons
    assert level == "HEALTHY" and "below the detection level" in reasons[-1]
