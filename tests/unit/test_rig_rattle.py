"""A play's rattle: the current rough along the whole travel (bench/rig/features.py
`roughness`, a naming-only feature), and the families named beside a periodic line with
no spot of its own (bench/rig/naming.py `attribute`, rule 3)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.rig import baseline as B
from bench.rig import naming as N
from bench.rig import population as P
from bench.rig.cycles import Cycle
from bench.rig.features import NAMING_ONLY, assess, cycle_features
from bench.rig.rattle import roughness
from tests.unit.test_rig_naming import healthy_runs, lagging

LEAD = 5.0


@pytest.fixture(scope="module")
def cycles():
    return healthy_runs(51)


@pytest.fixture(scope="module")
def base(cycles):
    return B.build(cycles)


def chatter(c: Cycle, stroke: str, amps: float, seed: int) -> Cycle:
    """White current noise of `amps` added on one stroke (a nut moving within its play)."""
    seg = next(s for s in c.segments() if s.name == stroke)
    c.current_a[seg.start:seg.stop] += amps * np.random.default_rng(seed).standard_normal(
        len(seg))
    return c


def test_white_noise_of_the_baseline_spread_is_about_one():
    rng = np.random.default_rng(52)
    std = np.full(400, 0.02)
    pos = np.linspace(30, 130, 400)
    assert roughness(0.02 * rng.standard_normal(400), std, pos, LEAD) == pytest.approx(
        1.0, abs=0.15)
    # twice the noise: four times the squares of its differences (the median square)
    assert roughness(0.04 * rng.standard_normal(400), std, pos, LEAD) == pytest.approx(
        4.0, rel=0.15)
    assert np.isnan(roughness(np.zeros(5), std[:5], pos[:5], LEAD))
    # a nut that did not move (its lead's line a constant): still a number, no error
    assert roughness(0.02 * rng.standard_normal(400), std, np.full(400, 80.0),
                     LEAD) == pytest.approx(1.0, abs=0.2)


def test_a_spot_is_not_a_rattle():
    # a transient over a few samples (a spot passed) moves a few differences only
    rng = np.random.default_rng(58)
    std = np.full(120, 0.02)
    pos = 30 + 0.96 * np.arange(120)
    noise = 0.02 * rng.standard_normal(120)
    spot = np.zeros(120)
    spot[60:64] = 0.3                      # 15 x the noise over 4 samples
    alone = roughness(noise, std, pos, LEAD)
    assert roughness(noise + spot, std, pos, LEAD) == pytest.approx(alone, rel=0.3)
    # a rattle along the whole travel: every difference grows
    assert roughness(noise + 0.04 * rng.standard_normal(120), std, pos, LEAD) > 3 * alone


def test_a_level_a_slope_and_the_lead_line_are_not_a_rattle():
    rng = np.random.default_rng(53)
    std = np.full(300, 0.02)
    pos = 30 + 0.96 * np.arange(300)      # about 5 samples a lead, as on the rig
    noise = 0.02 * rng.standard_normal(300)
    alone = roughness(noise, std, pos, LEAD)
    smooth = (0.3 + 0.001 * np.arange(300)
              + 0.05 * np.sin(2 * np.pi * pos / LEAD + 0.4))  # a line 2.5 x the noise
    assert roughness(noise + smooth, std, pos, LEAD) == pytest.approx(alone, rel=1e-6)
    # without the lead the line stays in, and its differences count
    assert roughness(noise + smooth, std, pos, None) > 2 * alone


def test_a_chattering_stroke_raises_the_rattle_a_level_does_not(base):
    lb = base.for_load(20)
    healthy = cycle_features(lb, lagging(np.random.default_rng(54)), LEAD)
    rough = cycle_features(lb, chatter(lagging(np.random.default_rng(54)), "in", 0.04, 55),
                           LEAD)
    c = lagging(np.random.default_rng(54))
    c.current_a[:] += 0.1
    level = cycle_features(lb, c, LEAD)
    assert healthy.scores["rattle"] < 2.0
    # one stroke rough is enough: the score is the rougher stroke's
    assert rough.scores["rattle"] > 3 * healthy.scores["rattle"]
    assert level.scores["rattle"] == pytest.approx(healthy.scores["rattle"], rel=1e-6)


def test_the_rattle_names_a_flagged_cycle_but_does_not_flag_one(base):
    f = cycle_features(base.for_load(20), chatter(lagging(np.random.default_rng(56)),
                                                  "out", 0.04, 57), LEAD)
    assert "rattle" in NAMING_ONLY
    alone = assess(f, {"rattle": 1.0, "localised": 1e9, "periodic": 1e9})
    assert not alone.flagged and alone.ratios["rattle"] > 1
    flagged = assess(f, {"rattle": 1.0, "localised": 1e9,
                         "periodic": f.scores["periodic"] / 2})
    assert flagged.flagged and (flagged.fault, flagged.effect) == (N.BACKLASH, "rattle")


def test_the_rattle_gets_a_threshold_from_the_healthy_runs(cycles):
    cal = P.calibrate(cycles, 0.05, LEAD)
    assert 0 < cal.thresholds["rattle"] < 10


def test_the_families_beside_a_periodic_line_with_no_spot_of_its_own():
    # a play's rattle or a drag lowered in both directions beside an unlocated line
    assert N.attribute({"periodic": 3.0, "rattle": 1.5}, 0, False) == (N.BACKLASH, "rattle")
    assert N.attribute({"periodic": 3.0, "level": 1.5}, -1, False) == (N.BACKLASH, "drag")
    # friction's level raised in both directions, as before
    assert N.attribute({"periodic": 3.0, "level": 1.5}, +1, False) == (N.FRICTION, "level")
    # a spot on the raceway beside it: the family furthest above its threshold
    assert N.attribute({"periodic": 3.0, "rattle": 1.5, "localised": 2.0}, 0, False) == (
        N.SPALL, "periodic")
    assert N.attribute({"periodic": 1.2, "rattle": 1.5, "localised": 1.1}, 0, False) == (
        N.BACKLASH, "rattle")
    # the periodic line alone is still a spall's
    assert N.attribute({"periodic": 3.0}, 0, False) == (N.SPALL, "periodic")
