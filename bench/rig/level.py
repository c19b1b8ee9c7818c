"""One level for all flagging features, set from the healthy calibration runs by a nested
leave-one-run-out (docs/decisions.md, "A family-wise level from a nested
leave-one-run-out").

For each calibration run r, every flagging feature's bound at level a is fitted from the
other runs' leave-one-run-out scores alone (`population.Loro`; the spreads pooled over
the loads, `spread.pooled`), and run r's cycles that any flagging feature flags are
counted; k(a) is the count over the runs and loads, N the cycles counted. The level is
the largest a in [alpha / n, alpha] with k(a) + 1 <= alpha (N + 1) (bisection on log a);
alpha / n when even it flags more, or when a run left out leaves fewer than
`spread.MIN_RUNS` runs. `nested=False` counts in-sample (every cycle against the bounds
fitted to it), for a comparison only. Used when `LEVEL_ENV` is "nested"; fault cycles
never enter it.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.rig.spread import MIN_RUNS, Spread, pooled

LEVEL_ENV = "BENCH_RIG_LEVEL"            # "nested": the family-wise level
LEVEL_LOG_ENV = "BENCH_RIG_LEVEL_LOG"    # a file each level set is appended to (JSON lines)

Fold = tuple[dict[str, dict[float, Spread]], dict[float, dict[str, np.ndarray]]]
# (the feature, its spread, a level) -> its threshold; (the feature, values) -> them
# transformed as its spread is modelled (`population.threshold_of`, `population.NULLS`)
Bound = Callable[[str, Spread, float], float]
Transform = Callable[[str, np.ndarray], np.ndarray]


def _folds(loros: dict[float, Any], keys: list[str], nested: bool, tr: Transform
           ) -> list[Fold] | None:
    """Per fold (a run left out, or all runs in-sample) the spreads of `keys` per load and
    the scores of the cycles it judges; None when a fold leaves fewer than `MIN_RUNS`
    runs at a load."""
    runs = sorted({r for lo in loros.values() for r in lo.of_run})
    out: list[Fold] = []
    for left in (runs if nested else [None]):
        fit = {ld: np.asarray([q != left for q in lo.of_run]) for ld, lo in loros.items()}
        if any(len(set(np.asarray(lo.of_run)[fit[ld]])) < MIN_RUNS
               for ld, lo in loros.items()):
            return None
        judged = {ld: ~m if nested else m for ld, m in fit.items()}
        sps: dict[str, dict[float, Spread]] = {}
        for k in keys:
            sps[k] = pooled(
                {ld: list(tr(k, np.asarray(lo.values[k], float)[fit[ld]]))
                 for ld, lo in loros.items()},
                {ld: list(np.asarray(lo.of_run)[fit[ld]]) for ld, lo in loros.items()})
        out.append((sps, {ld: {k: np.asarray(lo.scores[k], float)[judged[ld]] for k in keys}
                          for ld, lo in loros.items()}))
    return out


def _cycles(per_key: dict[str, np.ndarray]) -> int:
    return len(next(iter(per_key.values()))) if per_key else 0


def count(folds: list[Fold], a: float, bound: Bound) -> int:
    """k(a): the judged cycles flagged by any feature with every bound at level `a` (as
    `features.assess` flags: a finite score above a positive threshold)."""
    k = 0
    for sps, scores in folds:
        for ld, per_key in scores.items():
            hit = np.zeros(_cycles(per_key), bool)
            for key, s in per_key.items():
                thr = bound(key, sps[key][ld], a)
                if thr > 0 and math.isfinite(thr):
                    hit |= np.isfinite(s) & (s / thr > 1.0)
            k += int(hit.sum())
    return k


def family_level(loros: dict[float, Any], keys: list[str], alpha: float, floor: float,
                 bound: Bound, tr: Transform, nested: bool = True, steps: int = 40
                 ) -> tuple[float, dict[str, Any]]:
    """The level of the flagging features `keys` and what set it (k at the floor and at
    the level, N): see the module's text. `loros`: per load a `population.Loro`."""
    folds = _folds(loros, keys, nested, tr)
    if folds is None or not keys:
        return floor, {"reason": "fewer than 3 runs left", "level": floor}
    n = sum(_cycles(per) for _, sc in folds for per in sc.values())
    ok = lambda a: count(folds, a, bound) + 1 <= alpha * (n + 1)   # noqa: E731
    info = {"N": n, "k_floor": count(folds, floor, bound), "floor": floor}
    if not ok(floor):
        return floor, {**info, "level": floor, "k": info["k_floor"]}
    level = alpha
    if not ok(alpha):
        lo, hi = math.log(floor), math.log(alpha)
        for _ in range(steps):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if ok(math.exp(mid)) else (lo, mid)
        level = max(math.exp(lo), floor)
    return level, {**info, "level": level, "k": count(folds, level, bound)}


def level_of(loros: dict[float, Any], keys: list[str], alpha: float, floor: float,
             bound: Bound, tr: Transform) -> float:
    """The flagging features' level: `family_level` when `LEVEL_ENV` is "nested", else
    `floor` (alpha / n); each level set is appended to `LEVEL_LOG_ENV`'s file if given."""
    if os.environ.get(LEVEL_ENV, "") != "nested":
        return floor
    level, info = family_level(loros, keys, alpha, floor, bound, tr)
    path = os.environ.get(LEVEL_LOG_ENV)
    if path:
        runs = sorted({r for lo in loros.values() for r in lo.of_run})
        with open(path, "a") as fh:
            fh.write(json.dumps({"runs": runs, **info}) + "\n")
    return level
