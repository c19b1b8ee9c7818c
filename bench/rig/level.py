"""A level per load for the flagging features, set from the healthy calibration runs by a
nested leave-one-run-out (docs/decisions.md, "A family-wise level per load from a nested
leave-one-run-out").

For each calibration run r, every flagging feature's bound at level a is fitted from the
other runs' leave-one-run-out scores alone (`population.Loro`; the spreads pooled over
the loads, `spread.pooled`), and run r's cycles that any flagging feature flags are
counted at each load. A load's level is the largest a in [alpha / n, alpha] with
k(a) + 1 <= alpha (N + 1), k(a) and N that load's count and cycles (bisection on log a);
alpha / n when even it flags more, or when a run left out leaves fewer than
`spread.MIN_RUNS` runs. Fault cycles never enter it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.rig.spread import MIN_RUNS, Spread, pooled

# (the feature, its spread, a level) -> its threshold; (the feature, values) -> them
# transformed as its spread is modelled (`population.threshold_of`, `population.NULLS`)
Bound = Callable[[str, Spread, float], float]
Transform = Callable[[str, np.ndarray], np.ndarray]
# per run left out: the spreads of each feature per load, and per load the scores of the
# left-out run's cycles
Fold = tuple[dict[str, dict[float, Spread]], dict[float, dict[str, np.ndarray]]]


def folds(loros: dict[float, Any], keys: list[str], tr: Transform) -> list[Fold] | None:
    """One fold per calibration run left out; None when a fold leaves fewer than
    `MIN_RUNS` runs at a load."""
    runs = sorted({r for lo in loros.values() for r in lo.of_run})
    out: list[Fold] = []
    for left in runs:
        fit = {ld: np.asarray([q != left for q in lo.of_run]) for ld, lo in loros.items()}
        if any(len(set(np.asarray(lo.of_run)[fit[ld]])) < MIN_RUNS
               for ld, lo in loros.items()):
            return None
        sps = {k: pooled({ld: list(tr(k, np.asarray(lo.values[k], float)[fit[ld]]))
                          for ld, lo in loros.items()},
                         {ld: list(np.asarray(lo.of_run)[fit[ld]]) for ld, lo in loros.items()})
               for k in keys}
        out.append((sps, {ld: {k: np.asarray(lo.scores[k], float)[~fit[ld]] for k in keys}
                          for ld, lo in loros.items()}))
    return out


def count(fs: list[Fold], load: float, a: float, bound: Bound) -> int:
    """k(a) at `load`: its left-out cycles flagged by any feature with every bound at
    level `a` (as `features.assess` flags: a finite score above a positive threshold)."""
    k = 0
    for sps, scores in fs:
        per_key = scores[load]
        hit = np.zeros(len(next(iter(per_key.values()))), bool)
        for key, s in per_key.items():
            thr = bound(key, sps[key][load], a)
            if thr > 0 and math.isfinite(thr):
                hit |= np.isfinite(s) & (s / thr > 1.0)
        k += int(hit.sum())
    return k


def load_levels(loros: dict[float, Any], keys: list[str], alpha: float, floor: float,
                bound: Bound, tr: Transform, steps: int = 40
                ) -> tuple[dict[float, float], dict[float, dict[str, Any]]]:
    """Per load the level of the flagging features `keys`, and what set it (N, k at the
    floor and at the level): see the module's text."""
    fs = folds(loros, keys, tr) if keys else None
    if fs is None:
        return ({ld: floor for ld in loros},
                {ld: {"reason": "fewer than 3 runs left", "level": floor} for ld in loros})
    levels: dict[float, float] = {}
    info: dict[float, dict[str, Any]] = {}
    for ld in loros:
        n = sum(len(next(iter(sc[ld].values()))) for _, sc in fs)
        ok = lambda a, ld=ld, n=n: count(fs, ld, a, bound) + 1 <= alpha * (n + 1)  # noqa: E731
        level = floor
        if ok(floor):
            level = alpha
            if not ok(alpha):
                lo, hi = math.log(floor), math.log(alpha)
                for _ in range(steps):
                    mid = (lo + hi) / 2
                    lo, hi = (mid, hi) if ok(math.exp(mid)) else (lo, mid)
                level = max(math.exp(lo), floor)
        levels[ld] = level
        info[ld] = {"N": n, "floor": floor, "k_floor": count(fs, ld, floor, bound),
                    "level": level, "k": count(fs, ld, level, bound)}
    return levels, info
