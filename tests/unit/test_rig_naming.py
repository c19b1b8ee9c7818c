"""The fault named by physics (bench/rig/naming.py) and the spread between runs
(bench/rig/spread.py), on synthetic cycles and on numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.rig import baseline as B
from bench.rig import naming as N
from bench.rig import spread as S
from bench.rig.cycles import Cycle
from bench.rig.features import assess, cycle_features, rig_verdict, takeup_window


def lagging(rng, run=1, group=1, load=20.0):
    """A trapezoid whose nut lags its set-point after each reversal (a position loop's or
    a stepper's lag), as the Cranfield rig's does."""
    up = np.linspace(20, 140, 126)[:-1]
    sp = np.r_[up, np.full(75, 140.0), up[::-1] + 0.96]
    d = np.sign(np.r_[np.diff(sp), 0.0])
    k = np.arange(125) / 6.0
    bump = 4.0 * k * np.exp(1.0 - k)              # the lag peaks 6 samples in, then settles
    lag = np.r_[bump, np.zeros(75), -bump]
    pos = sp - lag + 0.01 * rng.standard_normal(len(sp))
    cur = 0.6 + 0.2 * d + 0.02 * rng.standard_normal(len(sp))
    return Cycle(np.arange(len(sp)) * 0.04, sp, pos, cur, load, run, group, "synthetic")


def healthy_runs(seed: int) -> list[Cycle]:
    """Three healthy runs of five `lagging` cycles each (the calibration of these tests)."""
    rng = np.random.default_rng(seed)
    return [lagging(rng, r, 10 * r + g) for r in (1, 2, 3) for g in range(5)]


@pytest.fixture(scope="module")
def base():
    return B.build(healthy_runs(31))


def lost_motion_at(c: Cycle, stroke: str, mm: float) -> Cycle:
    """The nut held back `mm` more while `stroke` takes up its reversal (the play taken up
    on that side only: a one-sided load keeps the nut on one flank elsewhere)."""
    seg = next(s for s in c.segments() if s.name == stroke)
    k = np.arange(len(seg))
    c.position_mm[seg.start:seg.stop] -= seg.direction * mm * np.clip(1 - k / 12, 0, None)
    return c


@pytest.mark.parametrize("stroke", ["out", "in"])
def test_lost_motion_at_either_reversal_is_named_backlash(base, stroke):
    """Which reversal shows a play depends on the load's sign: either one names it."""
    lb = base.for_load(20)
    assert takeup_window(lb.phases["out"]) > 5 and takeup_window(lb.phases["in"]) > 5
    c = lost_motion_at(lagging(np.random.default_rng(32)), stroke, 0.3)
    f = cycle_features(lb, c)
    other = "in" if stroke == "out" else "out"
    # the take-up's mean extra lag (0.3 mm fading over 12 samples of a ~30-sample window)
    assert 0.04 < f.takeup_mm[stroke] < 0.15 and abs(f.takeup_mm[other]) < 0.02
    assert abs(f.takeup_z[stroke]) > 5 * abs(f.takeup_z[other])
    j = assess(f, {"takeup": 3.0, "level": 3.0, "localised": 8.0})
    assert j.flagged and j.fault == N.BACKLASH and j.effect == "takeup"
    v = rig_verdict(base, f, {"takeup": 3.0})
    assert f"{stroke}-stroke +0.0" in v.text and v.text.startswith("backlash-like")


def test_a_healthy_cycle_takes_up_its_reversals_as_the_baseline(base):
    f = cycle_features(base.for_load(20), lagging(np.random.default_rng(33)))
    assert f.scores["takeup"] < 4.0


def test_attribution_rules():
    # friction: the level raised in both directions, the reversal current beside it
    assert N.attribute({"level": 3.0, "turn": 5.0}, +1, False) == (N.FRICTION, "level")
    # the same level raised in one direction only is not friction
    assert N.attribute({"level": 3.0}, 0, False) == (N.UNATTRIBUTED, "level")
    # lowered in both: the preload's drag lost
    assert N.attribute({"level": 3.0, "periodic": 2.0}, -1, False) == (N.BACKLASH, "drag")
    # a lag of the nut is a play's even beside a stronger periodic current
    assert N.attribute({"reversal": 1.5, "periodic": 6.0}, 0, False) == (N.BACKLASH,
                                                                        "reversal")
    # a spot on the raceway alone
    assert N.attribute({"periodic": 2.0, "localised": 3.0}, 0, False) == (N.SPALL,
                                                                         "localised")
    # friction and a play both, neither clearly ahead: not a guess
    assert N.attribute({"level": 2.0, "takeup": 3.0}, +1, False)[0] == N.AMBIGUOUS
    assert N.attribute({"level": 7.0, "takeup": 3.0}, +1, False)[0] == N.FRICTION
    assert N.attribute({"level": 1.2, "takeup": 3.0}, +1, False)[0] == N.BACKLASH
    # the current at a reversal alone cannot tell a breakaway from a play's impact
    assert N.attribute({"turn": 2.0}, 0, False) == (N.AMBIGUOUS, "turn")
    assert N.TEXT[N.AMBIGUOUS] == "friction or backlash: indistinguishable on this log"
    # an index of a position offset in every phase under a one-sided load
    assert N.attribute({"index": 4.0}, 0, True) == (N.BACKLASH, "offset")
    assert N.attribute({"index": 4.0}, 0, False) == (N.UNATTRIBUTED, "index")


def test_expected_families_of_the_labels():
    assert N.expected_fault("backlash") == N.BACKLASH
    assert N.expected_fault("lackLubrication") == N.FRICTION
    assert N.expected_fault("spalling") == N.SPALL
    assert N.expected_fault("normal") is None
    assert not N.is_correct(N.AMBIGUOUS, N.BACKLASH)


def test_spread_between_and_within_runs():
    rng = np.random.default_rng(5)
    runs = np.repeat(np.arange(6), 50)
    v = 3.0 * rng.standard_normal(6)[runs] + rng.standard_normal(300)
    sp = S.spread(v, runs)
    assert not sp.provisional and sp.runs == 6 and sp.cycles == 300
    assert sp.within == pytest.approx(1.0, rel=0.25)
    assert sp.between > 2.0 and sp.dof <= 5
    assert sp.predictive == pytest.approx(sp.between * (1 + 1 / 6) + sp.within * (1 + 1 / 300))
    # a new run's cycle: the bound covers the runs' spread, not the cycles' alone
    assert sp.upper(0.01) - sp.mean > 3.0 * math.sqrt(sp.between)


def test_runs_that_agree_give_the_bound_of_independent_cycles():
    """Runs whose means differ by no more than their cycles' noise (MSB <= MSW): every
    cycle an independent draw. Runs that differ a little: the between-run spread is
    known to R - 1 degrees of freedom, and the bound says so (wider)."""
    runs = np.repeat(np.arange(4), 10)
    same = np.tile(np.linspace(-1.5, 1.5, 10), 4)          # identical run means
    sp = S.spread(same, runs)
    assert sp.between == 0.0 and sp.dof == pytest.approx(39)
    assert sp.within == pytest.approx(np.var(same, ddof=1))
    assert sp.upper(0.05) < sp.mean + 1.7 * math.sqrt(sp.predictive)
    differ = same + np.repeat([0.0, 0.6, -0.6, 0.3], 10)
    wide = S.spread(differ, runs)
    assert wide.between > 0 and wide.dof == pytest.approx(3)


def test_two_runs_are_provisional():
    sp = S.spread([1.0, 1.1, 0.9, 2.0, 2.1, 1.9], [1, 1, 1, 2, 2, 2])
    assert sp.provisional and sp.between == 0.0 and sp.dof == 5


def test_the_loads_pool_their_mean_squares_and_keep_their_means():
    rng = np.random.default_rng(7)
    runs = np.repeat(np.arange(4), 5)
    vals = {ld: ld + 0.5 * rng.standard_normal(4)[runs] + 0.1 * rng.standard_normal(20)
            for ld in (1.0, 2.0, 3.0)}
    one = S.spread(vals[1.0], runs)
    pooled = S.pooled(vals, {ld: runs for ld in vals})
    assert [round(p.mean) for p in pooled.values()] == [1, 2, 3]
    assert len({round(p.within, 12) for p in pooled.values()}) == 1
    assert pooled[1.0].dof >= one.dof            # 9 between-run dof instead of 3


def test_a_verdict_against_two_runs_says_it_is_provisional():
    rng = np.random.default_rng(8)
    base = B.build([lagging(rng, r, 10 * r + g) for r in (1, 2) for g in range(5)])
    f = cycle_features(base.for_load(20), lagging(rng))
    v = rig_verdict(base, f, {"level": 100.0})
    assert v.provisional and v.level.name == "HEALTHY"
    assert "with a provisional baseline (2 healthy runs" in v.text
    d = v.to_dict()
    assert d["provisional"] and d["judged"] and not d["flagged"] and d["fault"] == ""
