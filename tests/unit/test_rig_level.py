"""The per-load level of the flagging features from a nested leave-one-run-out
(bench/rig/level.py): each load's calibration cycles counted against bounds fitted
without their run, so a load with a run off the others keeps alpha / n while another
load's level rises."""

from __future__ import annotations

import numpy as np

from bench.rig import level as L
from bench.rig import population as P

ALPHA = 0.05
WITHIN = np.array([-0.1, -0.05, 0.0, 0.05, 0.1])


def bound(k, sp, a):
    return P.threshold_of(sp, a, P.NULLS.get(k, ("log", 0)))


def tr(k, v):
    return P._transform(P.NULLS.get(k, ("log", 0))[0], v)


def loro(effects: list[float], load: float, key: str = "localised") -> P.Loro:
    """One load's leave-one-run-out scores of a log-normal feature: run r's cycles at
    exp(effects[r] + WITHIN)."""
    of_run, logs = [], []
    for r, e in enumerate(effects, start=1):
        of_run += [r] * len(WITHIN)
        logs += list(e + WITHIN)
    vals = list(np.exp(logs))
    return P.Loro(load, sorted(set(of_run)), {key: list(vals)}, {key: list(vals)}, of_run,
                  [1.0] * len(of_run))


def test_a_load_with_a_run_off_keeps_the_floor_and_another_rises():
    loros = {-40.0: loro([0.0, 0.0, 0.0, 0.0], -40.0), 40.0: loro([0.0, 0.05, -0.05, 2.0], 40.0)}
    floor = ALPHA / 8
    levels, info = L.load_levels(loros, ["localised"], ALPHA, floor, bound, tr)
    assert info[40.0]["N"] == 20 and info[40.0]["k_floor"] == 5
    assert levels[40.0] == floor
    assert levels[-40.0] > floor and info[-40.0]["k"] == 0


def test_the_level_is_the_largest_with_no_flagged_cycle_of_twenty():
    # run 4 sits 0.6 above the others: with it left out, its top cycle sets the level
    loros = {20.0: loro([0.0, 0.1, -0.1, 0.6], 20.0)}
    floor = ALPHA / 8
    levels, info = L.load_levels(loros, ["localised"], ALPHA, floor, bound, tr)
    fs = L.folds(loros, ["localised"], tr)
    a = levels[20.0]
    assert floor < a < ALPHA
    assert L.count(fs, 20.0, a, bound) == 0            # 0 + 1 <= 0.05 * 21
    assert L.count(fs, 20.0, a * 1.001, bound) >= 1


def test_two_runs_keep_the_floor():
    loros = {20.0: loro([0.0, 0.0], 20.0)}
    levels, info = L.load_levels(loros, ["localised"], ALPHA, ALPHA / 8, bound, tr)
    assert levels[20.0] == ALPHA / 8 and info[20.0]["reason"].startswith("fewer")
