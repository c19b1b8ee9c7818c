"""The flagging features' family-wise level from a nested leave-one-run-out
(bench/rig/level.py): each calibration run's cycles counted against bounds fitted
without that run, so a run off the others counts where the in-sample count does not."""

from __future__ import annotations

import math

import numpy as np

from bench.rig import level as L
from bench.rig import population as P

ALPHA = 0.05
HOOKS = (P.bound_at, P.transformed)
WITHIN = np.array([-0.1, -0.05, 0.0, 0.05, 0.1])


def loro(effects: list[float], keys: tuple[str, ...] = ("localised",), load: float = 20.0,
         noise: np.ndarray | None = None) -> P.Loro:
    """One load's leave-one-run-out scores of log-normal features: run r's cycles at
    exp(effects[r] + WITHIN) (or `noise[r]`)."""
    of_run, logs = [], []
    for r, e in enumerate(effects, start=1):
        w = WITHIN if noise is None else noise[r - 1]
        of_run += [r] * len(w)
        logs += list(e + w)
    vals = list(np.exp(logs))
    return P.Loro(load, sorted(set(of_run)), {k: list(vals) for k in keys},
                  {k: list(vals) for k in keys}, of_run, [1.0] * len(of_run))


def test_a_run_off_the_others_counts_nested_but_not_in_sample():
    loros = {20.0: loro([0.0, 0.05, -0.05, 2.0])}
    keys = ["localised"]
    inside = L._folds(loros, keys, nested=False, tr=P.transformed)
    nested = L._folds(loros, keys, nested=True, tr=P.transformed)
    # in-sample: run 4 widens the bound it is judged against, and no cycle is above it
    assert L.count(inside, ALPHA, P.bound_at) == 0
    # nested: with run 4 left out, runs 1-3 agree and every cycle of run 4 is above
    assert L.count(nested, ALPHA / 8, P.bound_at) == 5
    a_in, _ = L.family_level(loros, keys, ALPHA, ALPHA / 8, *HOOKS, nested=False)
    a_nest, info = L.family_level(loros, keys, ALPHA, ALPHA / 8, *HOOKS, nested=True)
    assert a_in == ALPHA
    assert a_nest == ALPHA / 8 and info["k_floor"] == 5 and info["N"] == 20


def test_runs_that_agree_allow_the_whole_alpha():
    loros = {20.0: loro([0.0, 0.0, 0.0, 0.0])}
    a, info = L.family_level(loros, ["localised"], ALPHA, ALPHA / 8, *HOOKS)
    assert a == ALPHA and info["k"] == 0


def test_the_level_is_the_largest_the_count_allows():
    rng = np.random.default_rng(4)
    keys = ["localised", "takeup", "turn", "dwell", "index"]
    loros = {ld: loro(list(rng.normal(0, 0.2, 4)), tuple(keys), ld,
                      rng.normal(0, 0.2, (4, 5))) for ld in (-40.0, 20.0, 40.0)}
    floor = ALPHA / 8
    a, info = L.family_level(loros, keys, ALPHA, floor, *HOOKS)
    # in-sample no cycle is above even at alpha: the level would be alpha
    assert L.family_level(loros, keys, ALPHA, floor, *HOOKS, nested=False)[0] == ALPHA
    folds = L._folds(loros, keys, nested=True, tr=P.transformed)
    n = info["N"]
    assert n == 60
    assert floor < a < ALPHA           # set by the count, neither bound of the interval
    assert L.count(folds, a, P.bound_at) + 1 <= ALPHA * (n + 1)
    assert L.count(folds, a * 1.001, P.bound_at) + 1 > ALPHA * (n + 1)


def test_two_runs_leave_no_between_run_spread_and_keep_the_floor():
    loros = {20.0: loro([0.0, 2.0])}
    a, _ = L.family_level(loros, ["localised"], ALPHA, ALPHA / 8, *HOOKS)
    assert a == ALPHA / 8


def test_thresholds_use_the_level_for_flagging_features_only(monkeypatch):
    loros = {20.0: loro([0.0, 0.0, 0.0, 0.0], ("localised", "dwell", "rattle"))}
    for k in P.FEATURES:
        loros[20.0].scores.setdefault(k, [])
    base = P.thresholds(loros)[20.0].thresholds
    monkeypatch.setenv(L.LEVEL_ENV, "nested")
    fw = P.thresholds(loros)[20.0].thresholds
    # two flagging features at alpha / 2 each without it; the runs agree and the nested
    # count allows the whole alpha: lower thresholds
    assert fw["localised"] < base["localised"] and fw["dwell"] < base["dwell"]
    assert math.isclose(fw["rattle"], base["rattle"])      # naming-only: alpha / n kept
