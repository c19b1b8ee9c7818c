"""`bench rig baseline --update` on synthetic runs whose current moves from run to run: a
healthy drift is absorbed, a step is refused, and a slow friction growth, each run inside
the current spread, is still found (against the first baseline) instead of absorbed."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.rig import update as U
from bench.rig.cycles import Cycle


def cycle(rng, run, group, offset=0.0, friction=0.0):
    up = np.linspace(20, 140, 126)[:-1]
    sp = np.r_[up, np.full(75, 140.0), up[::-1] + 0.96]
    d = np.sign(np.r_[np.diff(sp), 0.0])
    lag = np.convolve(np.r_[np.zeros(4), d], np.ones(5) / 5, mode="valid")[:len(sp)]
    pos = sp - 2.0 * lag + 0.01 * rng.standard_normal(len(sp))
    cur = (0.6 + 0.2 * d + 0.02 * rng.standard_normal(len(sp))
           + (offset + friction) * (d != 0))
    return Cycle(np.arange(len(sp)) * 0.04, sp, pos, cur, 20.0, run, group, "synthetic")


def run(rng, r, offset=None, friction=0.0, n=5):
    off = 0.003 * rng.standard_normal() if offset is None else offset
    return [cycle(rng, r, 100 * r + g, off, friction) for g in range(n)]


@pytest.fixture(scope="module")
def first():
    rng = np.random.default_rng(3)
    cycles = [c for r in (1, 2, 3, 4, 5) for c in run(rng, r)]
    base, notes = U.build(cycles, ["synthetic.csv"], None, "", 0.05)
    return base, notes


def test_the_baseline_keeps_its_cycles_and_its_first_thresholds(first):
    base, notes = first
    assert not notes
    kept = U.unpack(base.store["cycles"])
    assert len(kept) == 25 and {c.run for c in kept} == {1, 2, 3, 4, 5}
    assert base.store["anchor"]["20"]["runs"] == [1, 2, 3, 4, 5]
    assert base.thresholds["20"]["provisional"] is False


def test_two_runs_give_a_provisional_baseline_and_a_third_makes_it_whole():
    rng = np.random.default_rng(4)
    base, _ = U.build([c for r in (1, 2) for c in run(rng, r)], ["s.csv"], None, "", 0.05)
    assert base.thresholds["20"]["provisional"] is True
    assert base.for_load(20.0).provisional
    more, dec = U.update(base, run(rng, 3))
    assert [d["kind"] for d in dec] == ["drift"] and dec[0]["added"]
    assert more.thresholds["20"]["provisional"] is False


def test_healthy_runs_are_absorbed_as_drift(first):
    base, _ = first
    rng = np.random.default_rng(5)
    for r in (6, 7, 8):
        base, dec = U.update(base, run(rng, r))
        assert dec[0]["kind"] == "drift" and dec[0]["added"], dec
    assert base.for_load(20.0).runs == [1, 2, 3, 4, 5, 6, 7, 8]
    assert base.store["anchor"]["20"]["runs"] == [1, 2, 3, 4, 5]   # the anchor stays


def test_a_step_is_refused_and_force_adds_it(first):
    base, _ = first
    rng = np.random.default_rng(6)
    same, dec = U.update(base, run(rng, 6, friction=0.15))
    assert dec[0]["kind"] == "step" and not dec[0]["added"] and same is base
    assert "flagged against the current baseline" in dec[0]["why"]
    forced, dec = U.update(base, run(rng, 6, friction=0.15), force=True)
    assert dec[0]["added"] and dec[0]["forced"] and 6 in forced.for_load(20.0).runs
    assert "added anyway (--force)" in U.text(dec)[0]


def test_a_run_already_in_the_baseline_is_an_error(first):
    base, _ = first
    with pytest.raises(BenchError, match="already in the baseline"):
        U.update(base, run(np.random.default_rng(7), 2))


def slow_growth(base, rng, step, runs, anchored=True):
    """Runs 6, 7, ... with friction growing by `step` A a run, each added when the
    update takes it for drift; the first run refused and its kind (None: all added)."""
    if not anchored:
        base = U.B.Baseline(base.loads, base.sources, "", None, base.thresholds, "",
                            {k: v for k, v in base.store.items() if k != "anchor"})
    for k, r in enumerate(range(6, 6 + runs), start=1):
        base, dec = U.update(base, run(rng, r, friction=step * k))
        if not dec[0]["added"]:
            return r, dec[0]["kind"]
    return None, None


def test_a_slow_growth_is_found_not_absorbed(first):
    """Friction growing by 0.01 A a run (three times the runs' own spread): the first runs are
    taken for drift and added, and the growth is refused before it has reached ten times
    a step, not absorbed for ever."""
    base, _ = first
    stop, kind = slow_growth(base, np.random.default_rng(8), 0.01, 16)
    assert stop is not None and kind in ("step", "slow"), (stop, kind)
    assert 6 < stop <= 16                 # drift at first, refused at 0.1 A at the latest


def test_the_first_baseline_finds_what_a_drifted_one_takes_for_healthy(first):
    """A baseline that absorbed worn runs (added with --force, friction 0.02-0.08 A) has
    moved and widened: a run at 0.10 A is within its spread, so by it alone the run is
    drift. Against the first baseline it is a change: a slow change, not added."""
    base, _ = first
    rng = np.random.default_rng(10)
    for r, f in zip((6, 7, 8, 9), (0.02, 0.04, 0.06, 0.08), strict=True):
        base, _ = U.update(base, run(rng, r, friction=f), force=True)
    kept = U.unpack(base.store["cycles"])
    new = run(rng, 10, friction=0.10)
    kind, why = U.decide(base, kept, new, 0.05)
    assert kind == "slow" and "against the first baseline (runs 1,2,3,4,5: level)" in why
    no_anchor = U.B.Baseline(base.loads, base.sources, "", None, base.thresholds, "",
                             {k: v for k, v in base.store.items() if k != "anchor"})
    assert U.decide(no_anchor, kept, new, 0.05)[0] == "drift"


def test_update_refuses_a_baseline_without_kept_cycles(first):
    base, _ = first
    old = U.B.Baseline(base.loads, base.sources, "old.json", None, base.thresholds)
    with pytest.raises(BenchError, match="keeps no cycles"):
        U.update(old, run(np.random.default_rng(9), 4))
