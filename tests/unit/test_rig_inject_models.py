"""The fault models of `bench rig inject` (bench/rig/inject.py) on synthetic cycles: the
play operator, and the current faults acting on the strokes only."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.rig import inject as I
from bench.rig.cycles import Cycle


def cycle() -> Cycle:
    """A trapezoid: out-stroke 20 -> 140 mm over 50 samples, 20 samples dwell, in-stroke."""
    sp = np.r_[np.linspace(20, 140, 50), np.full(20, 140.0), np.linspace(140, 20, 50)]
    return Cycle(np.arange(len(sp)) / 25.0, sp, sp.copy(), np.full(len(sp), 1.0), 40.0,
                 3, 1, "test")


def test_play_operator_stays_until_the_play_is_taken_then_trails_by_half():
    x = np.r_[np.linspace(0, 10, 101), np.linspace(10, 0, 101)]
    y = I.play(x, 2.0, first_direction=1)
    assert y[0] == pytest.approx(1.0)                   # trailing the motion before
    assert np.all(y[:21] == pytest.approx(1.0))         # play taken up over 2 mm
    np.testing.assert_allclose(y[30:101], x[30:101] - 1.0)
    assert np.all(y[101:121] == pytest.approx(9.0))     # reversal: stays for 2 mm
    np.testing.assert_allclose(y[130:], x[130:] + 1.0)
    np.testing.assert_allclose(I.play(x, 0.0, 1), x)


def test_a_play_under_a_one_sided_load_shifts_every_sample_towards_the_load():
    """The nut stays on the loaded flank: half the play in every sample, towards the side
    the load pushes it, the current unchanged; named right as backlash."""
    c = cycle()
    shifted = I.loaded_play(c, 0.4, push=-1.0)
    np.testing.assert_allclose(shifted.position_error_mm, c.position_error_mm + 0.2)
    np.testing.assert_array_equal(shifted.current_a, c.current_a)
    assert I.Scales(40.0, 0.05, 0.3, 0.5, 80.0, -1.0).physical("loaded_play", 2.0) == 0.6
    assert I.EXPECTED["loaded_play"] == "backlash"


def test_backlash_changes_the_position_error_only():
    c = cycle()
    b = I.backlash(c, 1.0)
    np.testing.assert_array_equal(b.current_a, c.current_a)
    err = b.position_error_mm
    assert np.median(err[10:50]) == pytest.approx(0.5)      # out-stroke: lags by b/2
    assert np.median(err[80:]) == pytest.approx(-0.5)       # in-stroke: the other way


def test_current_faults_act_on_the_strokes_only():
    c = cycle()
    moving = I.moving(c)
    assert moving.sum() == 99 and not moving[55:68].any()
    f = I.friction(c, 0.2)
    np.testing.assert_allclose(f.current_a - c.current_a, 0.2 * moving)
    loc = I.localised(c, 0.3, at_mm=80.0)
    d = loc.current_a - c.current_a
    assert set(np.round(d, 6)) == {0.0, 0.3}
    hit = c.position_mm[d > 0]
    assert hit.min() >= 80 - I.NUT_MM / 2 and hit.max() <= 80 + I.NUT_MM / 2
    assert (d > 0)[:50].any() and (d > 0)[70:].any()          # both strokes
    p = I.periodic(c, 0.1, 5.0)
    dp = p.current_a - c.current_a
    np.testing.assert_allclose(dp, 0.1 * np.sin(2 * np.pi * c.position_mm / 5.0) * moving,
                               atol=1e-12)


def test_sizes_and_kinds_are_checked():
    assert I.parse_sizes("2,0.5,2") == (0.5, 2.0)
    with pytest.raises(BenchError, match="finite number > 0"):
        I.parse_sizes("nan")
    with pytest.raises(BenchError, match="unknown wear"):
        I.parse_kinds("wear")
    assert I.size_at({"1": {"rate": 0.95}, "2": {"rate": 0.8}, "4": {"rate": 1.0}},
                     (1.0, 2.0, 4.0), "rate") == 4.0


def _features(**scores: float):
    from bench.rig.features import FEATURES, CycleFeatures
    nan = float("nan")
    full = {k: scores.get(k, 0.0) for k in FEATURES}
    # the current raised in both strokes: a level above threshold reads as friction
    return CycleFeatures("c", "s", 40.0, 3, 1, full, nan, nan, "-", nan, nan, 1.0, 1.0)


@pytest.mark.parametrize("scores,named", [
    ({"level": 6.0, "localised": 1.2}, "level"),       # friction leaks into the scan
    ({"level": 1.2, "localised": 6.0}, "localised"),   # a spot moves the level a little
    ({"level": 3.0, "index": 9.0}, "level"),           # a catch-all only when alone
    ({"index": 9.0, "dwell": 2.0}, "index"),
    ({"periodic": 2.0, "localised": 5.0}, "localised"),
    ({"reversal": 2.0, "level": 1.5, "index": 4.0}, "reversal"),
])
def test_judge_names_by_tier_and_ratio(scores, named):
    from bench.rig.features import FEATURES, judge
    thr = {k: 1.0 for k in FEATURES}
    assert (v := judge(_features(**scores), thr)).flagged and v.effect == named
    assert not (v := judge(_features(), thr)).flagged and v.effect == "none"
