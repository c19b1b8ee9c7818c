"""`bench.signals.estimators`: the command's fundamental and the motion regimes, each estimated
by one function the HUMS report, the gap, the rig cycles and the usage counters call."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.signals import estimators as E
from bench.signals.trace import Trace

pytestmark = pytest.mark.unit


def test_a_stated_fundamental_wins_when_it_is_a_frequency():
    y = np.sin(2 * np.pi * 2.0 * np.arange(4000) * 1e-3)
    assert E.fundamental_hz(3.0, y, 1e-3) == 3.0
    assert E.fundamental_hz((None, "x", -1.0, math.nan, 0.0, 5.0)) == 5.0   # first usable
    assert math.isnan(E.fundamental_hz(None))                              # no signal
    assert E.fundamental_hz((), y, 1e-3) == pytest.approx(2.0, abs=0.25)   # the band reference
    assert E.fundamental_hz((), y, 1e-3, periodic=True) == pytest.approx(2.0)


def test_a_step_has_no_period_but_a_band_reference():
    t = np.arange(4000) * 1e-3
    step = np.where(t > 2.0, 1.0, 0.0)
    assert math.isnan(E.fundamental_hz((), step, 1e-3, periodic=True))
    assert math.isnan(E.fundamental_hz((), np.ones(4000), 1e-3, periodic=True))
    assert math.isnan(E.fundamental_hz((), np.zeros(4000), 1e-3))
    v = np.sign(np.sin(2 * np.pi * 1.0 * t)) * 0.01       # a triangle's velocity ...
    v[::500] = 50.0                                          # ... with a set-point's spikes
    assert E.fundamental_hz((), v, 1e-3, clip_percentile=99) == pytest.approx(1.0, abs=0.25)


def test_a_period_is_a_whole_number_of_samples():
    dt = 0.04
    y = np.sin(2 * np.pi * 0.37 * np.arange(1000) * dt)
    f0 = E.fundamental_hz((), y, dt, periodic=True)
    assert 1.0 / (f0 * dt) == pytest.approx(round(1.0 / (f0 * dt)), abs=1e-9)


def test_motion_regimes_split_by_speed_with_the_edge_on_either_side():
    v = np.array([0.0, -0.5, 0.5, 1.0, -2.0, 10.0, math.nan])
    assert E.motion_regimes(v, (0.5, 2.0)).tolist() == [0, 0, 0, 1, 1, 2, -1]
    assert E.motion_regimes(v, (0.5, 2.0), at_edge="upper").tolist() == [0, 1, 1, 1, 2, 2, -1]
    assert E.motion_direction(v, 0.5).tolist() == [0, 0, 0, 1, -1, 1, 0]
    assert E.moving_threshold(np.array([0.0, -3.0, 1.0])) == pytest.approx(0.06)
    assert E.moving_threshold(np.zeros(5)) == E.MOVING_FLOOR


def test_a_rig_log_that_never_moves_has_no_motion_regime():
    """A constant set-point's np.gradient against a float time axis is ~1e-13, not 0: the
    gap's rig regimes read it as moving when the moving threshold's floor was 2e-14
    (0.02 x 1e-12), below that rounding noise; the one floor (1e-12) keeps it at rest."""
    from bench.rig.riggap import _regimes
    n, dt = 2000, 1e-3
    tr = Trace({"t_s": np.arange(n) * dt, "setpoint_position_m": np.full(n, 0.3)})
    reg = _regimes(tr)
    assert not reg["cruise"].any() and not reg["start_stop"].any() and reg["dwell"].all()
    assert not reg["extend"].any() and not reg["retract"].any()
