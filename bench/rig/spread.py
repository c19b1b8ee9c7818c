"""The spread between healthy runs, not only within them.

A rig's healthy runs differ from one another by more than their cycles differ within a
run: the drive's current, the grease's temperature and the sensors' zeros move between
runs (Cranfield, 40 kgf: the in-stroke current of healthy run 6 is 3.8 within-run
standard deviations below the mean of runs 1-6). A threshold set from the cycles of a few
runs as if they were independent takes those runs' spread for the whole healthy spread,
and a healthy run it did not see is flagged.

So every healthy score is read as a one-way random-effects model (a hierarchical model
of runs and cycles):

    t_rc = mu + b_r + e_rc,   b_r ~ N(0, s_b^2) (between runs),  e_rc ~ N(0, s_w^2),

t a transform of the score that is near normal (`TRANSFORMS`). From R runs with n cycles
each, the one-way analysis of variance gives the mean squares MSB (R - 1 degrees of
freedom) and MSW (N - R), s_w^2 = MSW and s_b^2 = (MSB - MSW) / n. A cycle of a run
that is not among them varies about the estimated mean by

    V = s_b^2 (1 + 1/R) + s_w^2 (1 + 1/N) = MSB (1 + 1/R) / n + MSW (1 - 1/n),

and its upper prediction bound is mean + t(1 - alpha; nu) sqrt(V), nu from
Welch-Satterthwaite but at most R - 1 when a between-run spread is estimated. With runs
that agree (MSB not above MSW) nu is N - 1 and the bound is the usual one of independent
cycles; with runs that differ it widens, as it should: a few runs say little about the
next one. With fewer than `MIN_RUNS` runs the
between-run spread cannot be estimated; the bound is then that of independent cycles and
the result says it is provisional (`Spread.provisional`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

MIN_RUNS = 3        # fewer calibration runs: the between-run spread is not estimated


@dataclass(frozen=True)
class Spread:
    """The healthy spread of one transformed score over runs and cycles."""
    mean: float
    within: float          # s_w^2
    between: float         # s_b^2 (0 when the runs agree within their noise)
    runs: int
    cycles: int
    dof: float             # degrees of freedom of the predictive variance
    provisional: bool      # fewer than MIN_RUNS runs: `between` is not estimated

    @property
    def predictive(self) -> float:
        """V: the variance of one cycle of a new run about `mean`."""
        n = self.cycles / max(self.runs, 1)
        if self.provisional:
            return self.within * (1.0 + 1.0 / max(self.cycles, 1))
        return (self.between * (1.0 + 1.0 / self.runs)
                + self.within * (1.0 + 1.0 / self.cycles)) if n else float("nan")

    def upper(self, alpha: float) -> float:
        """The one-sided upper (1 - alpha) prediction bound of a new run's cycle."""
        from scipy.special import stdtrit
        return self.mean + float(stdtrit(self.dof, 1.0 - alpha)) * math.sqrt(self.predictive)

    def z(self, value: float) -> float:
        """A transformed score in units of the predictive spread."""
        return (value - self.mean) / math.sqrt(self.predictive) if self.predictive > 0 \
            else float("nan")

    def to_json(self) -> dict[str, float | int | bool]:
        return {"mean": self.mean, "within": self.within, "between": self.between,
                "runs": self.runs, "cycles": self.cycles, "dof": self.dof,
                "provisional": self.provisional}


@dataclass(frozen=True)
class _Anova:
    """One group of runs' one-way analysis of variance."""
    mean: float              # the mean of the run means (each run weighs the same)
    overall: float           # the mean of every value
    ssw: float
    ssb: float
    runs: int
    cycles: int
    n0: float


def _anova(values: Any, runs: Any) -> _Anova | None:
    v = np.asarray(values, float)
    r = np.asarray(runs)
    ok = np.isfinite(v)
    v, r = v[ok], r[ok]
    groups = [v[r == k] for k in np.unique(r)]
    groups = [g for g in groups if len(g)]
    big_r, big_n = len(groups), int(sum(len(g) for g in groups))
    if big_n < 2:
        return None
    means = np.array([g.mean() for g in groups])
    sizes = np.array([len(g) for g in groups], float)
    ssw = float(sum(((g - g.mean()) ** 2).sum() for g in groups))
    ssb = float(np.sum(sizes * (means - v.mean()) ** 2))
    n0 = ((big_n - float(np.sum(sizes ** 2)) / big_n) / (big_r - 1)) if big_r > 1 else 1.0
    return _Anova(float(np.mean(means)), float(v.mean()), ssw, ssb, big_r, big_n, n0)


def _from_anova(a: _Anova, msb: float, msw: float, dof_b: float, dof_w: float
                ) -> Spread:
    """The spread of one group from its mean and the (possibly pooled) mean squares."""
    big_r, big_n = a.runs, a.cycles
    if big_r < MIN_RUNS or big_n <= big_r:
        within = (a.ssw + a.ssb) / max(big_n - 1, 1)
        return Spread(a.overall, within, 0.0, big_r, big_n, float(max(big_n - 1, 1)), True)
    between = max((msb - msw) / a.n0, 0.0)
    if between == 0.0:          # the runs agree: every cycle an independent draw
        within = (msb * dof_b + msw * dof_w) / (dof_b + dof_w)
        return Spread(a.overall, within, 0.0, big_r, big_n, float(dof_b + dof_w), False)
    f = (1.0 + 1.0 / big_r) / a.n0            # V = f MSB + g MSW
    g = (1.0 + 1.0 / big_n) - f
    num = (f * msb + g * msw) ** 2
    den = (f * msb) ** 2 / dof_b + ((g * msw) ** 2 / dof_w if g > 0 else 0.0)
    dof = num / den if den > 0 else float(dof_b + dof_w)
    # a between-run spread is known to its own degrees of freedom at most: Satterthwaite's
    # count assumes chi-square mean squares, which a handful of runs' effects are not
    dof = min(dof, float(dof_b))
    return Spread(a.mean, msw, between, big_r, big_n, float(max(dof, 1.0)), False)


def spread(values: Sequence[float] | np.ndarray, runs: Sequence[Any] | np.ndarray) -> Spread:
    """The random-effects spread of `values` (one per cycle) grouped by `runs`
    (non-finite values are left out). Unbalanced runs use the usual n0 of the one-way
    model."""
    return pooled({0: values}, {0: runs})[0]


def pooled(values: dict[Any, Any], runs: dict[Any, Any]) -> dict[Any, Spread]:
    """Per group (a load), the spread of its values with the within- and between-run
    mean squares pooled over every group of at least `MIN_RUNS` runs (each group keeps its
    own mean). The runs of one rig differ by a similar amount at every load (the same
    warm-up, the same sensors), so the loads together estimate the between-run spread
    with the degrees of freedom of all of them: with 4 runs at each of 3 loads, 9 instead
    of 3 (chosen on healthy Cranfield runs alone: with 4 calibration runs of 6, one
    load's own mean squares flagged 7-8 % of the other runs' cycles at two loads, the
    pooled ones 1-4 %)."""
    an = {k: _anova(v, runs[k]) for k, v in values.items()}
    full = [a for a in an.values() if a is not None and a.runs >= MIN_RUNS
            and a.cycles > a.runs]
    dof_b = float(sum(a.runs - 1 for a in full))
    dof_w = float(sum(a.cycles - a.runs for a in full))
    msb = sum(a.ssb for a in full) / dof_b if dof_b else float("nan")
    msw = sum(a.ssw for a in full) / dof_w if dof_w else float("nan")
    out: dict[Any, Spread] = {}
    for k, a in an.items():
        if a is None:
            v = np.asarray(values[k], float)
            v = v[np.isfinite(v)]
            out[k] = Spread(float(v.mean()) if len(v) else float("nan"), float("nan"), 0.0,
                            0, len(v), 1.0, True)
        else:
            out[k] = _from_anova(a, msb, msw, dof_b, dof_w)
    return out
