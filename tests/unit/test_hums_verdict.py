"""One verdict (issue 10): `bench.hums.verdict.judge` is the report's verdict and the live
watcher's level; mode-aware, UNKNOWN without the index it rests on."""

from __future__ import annotations

import math

from bench.hums.indexes import Indexes
from bench.hums.live import LEVELS, LiveHums, PeriodResult
from bench.hums.verdict import UNKNOWN, judge
from bench.trace import MODE_IDLE, MODE_POSITION, MODE_SPEED


def ix(**kw) -> Indexes:
    return Indexes(0.0, 0.5, **kw)


def test_position_mode_rests_on_ci():
    assert judge(ix(ci=0.99, cp=1.0), MODE_POSITION)[0] == "HEALTHY"
    assert judge(ix(ci=0.90), MODE_POSITION)[0] == "DEGRADED"
    assert judge(ix(ci=0.70), MODE_POSITION)[0] == "WARNING"
    assert judge(ix(ci=0.40), MODE_POSITION)[0] == "FAILURE"
    # the harmonic Ci comes first when there is one
    assert judge(ix(ci=0.99, ci_harmonic=0.70), MODE_POSITION)[0] == "WARNING"


def test_no_index_no_verdict():
    level, reasons = judge(ix(cp=1.0), MODE_POSITION)           # Ci NaN
    assert level == UNKNOWN and reasons[0].startswith("Ci ")
    level, reasons = judge(ix(ci=0.99), MODE_SPEED)             # Cp NaN in speed mode
    assert level == UNKNOWN and reasons[0].startswith("Cp ")
    assert judge(ix(ci=0.99, cp=1.0), MODE_IDLE)[0] == UNKNOWN


def test_speed_mode_rests_on_cp_not_ci():
    assert judge(ix(ci=0.40, cp=1.0), MODE_SPEED)[0] == "HEALTHY"
    assert judge(ix(ci=0.99, cp=1.02), MODE_SPEED)[0] == "DEGRADED"


def test_lost_motion_counts():
    assert judge(ix(ci=0.99, lost_motion_m=20e-6, nominal_lost_motion_m=0.0),
                 MODE_POSITION)[0] == "DEGRADED"


def test_live_levels_name_the_verdicts():
    assert LEVELS[:4] == ("HEALTHY", "DEGRADED", "WARNING", "FAILURE")
    assert LEVELS[4] == UNKNOWN
    r = PeriodResult(1, 0, 0.0, ix(), LEVELS.index(UNKNOWN))
    assert r.row()["level"] == UNKNOWN


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
    assert LEVELS[out[0].level] == judge(out[0].indexes, MODE_POSITION)[0] == UNKNOWN
