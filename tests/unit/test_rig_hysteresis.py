"""Backlash as a position-error hysteresis over the take-ups of the reversals
(bench/rig/play.py `hysteresis`), a naming-only feature, and friction beside a
periodic line with no spot of its own (bench/rig/naming.py)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.rig import baseline as B
from bench.rig import naming as N
from bench.rig import population as P
from bench.rig.cycles import Cycle
from bench.rig.features import NAMING_ONLY, assess, cycle_features
from bench.rig.play import hysteresis
from tests.unit.test_rig_naming import healthy_runs, lagging, lost_motion_at


@pytest.fixture(scope="module")
def cycles():
    return healthy_runs(31)


@pytest.fixture(scope="module")
def base(cycles):
    return B.build(cycles)


def offset_in_takeups(c: Cycle, mm: float) -> Cycle:
    """The position error raised by `mm` alike while both strokes take up their reversal
    (not along the motion): a zero that moves between runs, not a play."""
    for s in c.segments():
        if s.name in ("out", "in"):
            k = np.arange(len(s))
            c.position_mm[s.start:s.stop] -= mm * np.clip(1 - k / 12, 0, None)
    return c


def test_the_hysteresis_of_the_takeups_adds_the_lags_along_the_motion():
    # a play at both reversals: both lags along the motion grow, the sum keeps both
    assert hysteresis({"out": 0.1, "in": 0.1}, {"out": 5.0, "in": 5.0}) == pytest.approx(
        0.2 / np.hypot(0.02, 0.02))
    # an offset seen as +d on one stroke and -d on the other cancels
    assert hysteresis({"out": 0.25, "in": -0.25}, {"out": 5.0, "in": -5.0}) == 0.0
    assert np.isnan(hysteresis({"out": 0.1}, {"out": 5.0}))


def test_a_play_at_both_reversals_is_a_hysteresis_a_moved_zero_is_not(base):
    lb = base.for_load(20)
    play = cycle_features(lb, lost_motion_at(lost_motion_at(
        lagging(np.random.default_rng(40)), "out", 0.3), "in", 0.3))
    zero = cycle_features(lb, offset_in_takeups(lagging(np.random.default_rng(40)), 0.3))
    healthy = cycle_features(lb, lagging(np.random.default_rng(40)))
    # both move the take-ups by as much (the takeup score cannot tell them apart) ...
    assert play.scores["takeup"] > 5 and zero.scores["takeup"] > 5
    # ... but only the play changes the lag along the motion at both reversals
    assert play.scores["hysteresis"] > 5 * zero.scores["hysteresis"]
    assert play.scores["hysteresis"] > 5 * healthy.scores["hysteresis"]
    assert play.hysteresis_signed > 0           # more lag
    thr = {"hysteresis": 3.0, "takeup": 1e9, "localised": 1e9}
    assert assess(zero, thr).effect != "hysteresis"


def test_the_hysteresis_names_a_flagged_cycle_but_does_not_flag_one(base):
    f = cycle_features(base.for_load(20), lost_motion_at(lost_motion_at(
        lagging(np.random.default_rng(41)), "out", 0.3), "in", 0.3))
    alone = assess(f, {"hysteresis": 1.0, "localised": 1e9, "takeup": 1e9})
    assert "hysteresis" in NAMING_ONLY
    assert not alone.flagged and alone.ratios["hysteresis"] > 1
    # flagged by another feature (here the localised scan): the nut's lag names backlash
    both = assess(f, {"hysteresis": 1.0, "localised": f.scores["localised"] / 2,
                      "takeup": 1e9})
    assert both.flagged and (both.fault, both.effect) == (N.BACKLASH, "hysteresis")


def test_a_naming_only_feature_takes_no_share_of_the_false_alarm_rate(cycles, monkeypatch):
    with_it = P.calibrate(cycles, 0.05).thresholds
    flagging = tuple(k for k in P.FEATURES if k not in NAMING_ONLY)
    monkeypatch.setattr(P, "FEATURES", flagging)
    without = P.calibrate(cycles, 0.05).thresholds
    assert "hysteresis" in with_it and "hysteresis" not in without
    for k in without:
        assert with_it[k] == pytest.approx(without[k])


def test_friction_beside_a_periodic_line_with_no_spot_of_its_own():
    # the level raised in both directions and a periodic line spread along the stroke
    assert N.attribute({"level": 1.5, "periodic": 3.0}, +1, False) == (N.FRICTION, "level")
    # a spot on the raceway (the localised scan above) beside it: the stronger family
    assert N.attribute({"level": 1.5, "periodic": 3.0, "localised": 2.0}, +1, False) == (
        N.SPALL, "periodic")
    # a level raised in one direction only is no friction: the periodic line is a spall's
    assert N.attribute({"level": 1.5, "periodic": 3.0}, 0, False) == (N.SPALL, "periodic")
