"""A play's weak signatures together (bench/rig/play.py `play_score`, a naming-only
feature): its score from the signatures' ratios to their thresholds, its threshold from
the healthy runs' leave-one-run-out scores (bench/rig/population.py `thresholds`), and
the family it names beside a periodic line with no spot (bench/rig/naming.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.rig import naming as N
from bench.rig import population as P
from bench.rig.features import NAMING_ONLY, assess, cycle_features
from bench.rig.play import PLAY_OF, play_score
from tests.unit.test_rig_naming import lagging
from tests.unit.test_rig_rattle import LEAD, base, cycles  # noqa: F401 (fixtures)

THR = {"hysteresis": 4.0, "reversal": 2.0, "takeup": 10.0, "rattle": 2.0}


def test_each_signature_at_its_threshold_scores_one():
    assert play_score({k: THR[k] for k in PLAY_OF}, THR) == pytest.approx(1.0)


def test_the_signatures_add_on_the_scale_of_their_nulls():
    at = {k: THR[k] for k in PLAY_OF}
    # a log-normal one (the rattle) at half its threshold: a factor 1/2
    assert play_score({**at, "rattle": 1.0}, THR) == pytest.approx(0.5)
    # a two-sided one (the hysteresis, |a normal| about 0) at 0: its ratio less 1, e^-1,
    # not the log of 0
    assert play_score({**at, "hysteresis": 0.0}, THR) == pytest.approx(math.exp(-1.0))
    # every signature at 0.9 of its threshold: the excesses added
    below = {k: 0.9 * THR[k] for k in PLAY_OF}
    assert play_score(below, THR) == pytest.approx(math.exp(2 * -0.1 + 2 * math.log(0.9)))
    # above one signature far above its threshold with the others at a healthy run's
    # (the study's healthy medians: a fifth to a third of their thresholds)
    one = {"hysteresis": 0.2 * 4.0, "reversal": 0.2 * 2.0, "takeup": 2.0 * 10.0,
           "rattle": 0.35 * 2.0}
    assert play_score(below, THR) > play_score(one, THR)


def test_a_missing_signature_or_threshold_gives_no_score():
    at = {k: THR[k] for k in PLAY_OF}
    assert math.isnan(play_score({**at, "takeup": float("nan")}, THR))
    assert math.isnan(play_score(at, {k: v for k, v in THR.items() if k != "rattle"}))


def test_the_play_gets_its_threshold_from_the_healthy_runs(cycles):  # noqa: F811
    cal = P.calibrate(cycles, 0.05, LEAD)
    assert "play" in NAMING_ONLY
    scores = np.asarray(cal.scores["play"])
    assert len(scores) == len(cal.score_runs) and np.isfinite(scores).all()
    # each held-out healthy score from that cycle's signatures and the thresholds set
    i = 3
    assert scores[i] == pytest.approx(play_score(
        {k: cal.scores[k][i] for k in PLAY_OF}, cal.thresholds))
    # an upper bound of the healthy scores: above most of them
    assert np.mean(scores < cal.thresholds["play"]) > 0.9


def test_the_play_names_a_flagged_cycle_but_does_not_flag_one(base):  # noqa: F811
    f = cycle_features(base.for_load(20), lagging(np.random.default_rng(61)), LEAD)
    thr = {k: f.scores[k] * 1.1 for k in PLAY_OF}       # each signature below its own
    thr["play"] = play_score(f.scores, thr) / 2          # together above
    alone = assess(f, {**thr, "localised": 1e9, "periodic": 1e9})
    assert not alone.flagged and alone.ratios["play"] == pytest.approx(2.0)
    beside = assess(f, {**thr, "localised": 1e9, "periodic": f.scores["periodic"] / 2})
    assert beside.flagged and (beside.fault, beside.effect) == (N.BACKLASH, "play")
    # without the play's threshold (an older baseline): the periodic line's spall
    old = assess(f, {k: v for k, v in thr.items() if k != "play"}
                 | {"localised": 1e9, "periodic": f.scores["periodic"] / 2})
    assert (old.fault, old.effect) == (N.SPALL, "periodic")
