"""The thesis' RUL algorithm (section 6.5, rows R1-R2): the Ci levels, the prediction of
a time of failure with its band, and the cubic trend fit extrapolated to failure.

Levels (the thesis' section 6.3/6.5): threshold 0.93, warning 0.80, failure 0.56 on the
current fidelity coefficient Ci (eq. 6.6). Once Ci falls below the threshold the points
are stored; when it falls below the warning level, a cubic is fitted to Ci(t) over the
points between the two crossings and extrapolated to 0.56: RUL = t(0.56) - t(warning)
(`thesis_predict`, figs. 6.14-6.15). Its band here comes from a residual bootstrap of
the cubic fit (beyond the thesis).

A `Prediction` (failure-time samples made at one time) is what every predictor returns:
this one, the fused one (`bench.hums.fusion`) and the scoring (`bench.hums.metrics`).
The run these predictions are made on is in `bench.hums.rul_run` (R1-R2) and
`bench.hums.campaign` (run-to-failure campaign).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

THRESHOLD, WARNING, FAILURE = 0.93, 0.80, 0.56
N_BOOT = 200


@dataclass
class Prediction:
    """A failure-time prediction made at `t_pred_s`: samples of the time of failure."""
    t_pred_s: float
    toe_samples: np.ndarray

    @property
    def toe_s(self) -> float:
        f = self.toe_samples[np.isfinite(self.toe_samples)]
        return float(np.median(self.toe_samples)) if len(f) * 2 > len(self.toe_samples) \
            else math.inf

    @property
    def rul_s(self) -> float:
        return self.toe_s - self.t_pred_s

    def band(self, lo: float = 5.0, hi: float = 95.0) -> tuple[float, float]:
        """Percentiles of the failure-time samples (inf = the fit predicts no failure)."""
        s = np.sort(np.where(np.isnan(self.toe_samples), np.inf, self.toe_samples))
        if not len(s):
            return math.inf, math.inf

        def q(p: float) -> float:
            return float(s[min(len(s) - 1, max(0, int(round(p / 100.0 * (len(s) - 1)))))])
        return q(lo), q(hi)


@dataclass
class ThesisResult:
    """The thesis' prediction: threshold and warning crossings, the cubic and its band."""
    t_threshold_s: float
    t_warning_s: float
    coeffs: list[float]               # cubic in (t - t_pred) / scale, highest first
    scale_s: float
    prediction: Prediction | None
    point_toe_s: float = math.nan     # failure time of the cubic fitted to the data

    @property
    def rul_s(self) -> float:
        return self.prediction.rul_s if self.prediction else math.nan


def first_below(t: np.ndarray, y: np.ndarray, level: float, after: float = -math.inf
                ) -> float:
    """The first time at or after `after` where y is below `level` (NaN if never)."""
    hit = np.flatnonzero((np.asarray(y) < level) & (np.asarray(t) >= after))
    return float(t[hit[0]]) if len(hit) else math.nan


def _cubic_toe(t: np.ndarray, y: np.ndarray, t_now: float, failure: float, degree: int,
               n_boot: int, rng: np.random.Generator, horizon_s: float
               ) -> tuple[np.ndarray, np.ndarray, float]:
    """Fit a polynomial of `degree` to y(t), bootstrap its residuals; the first time after
    t_now each fit reaches `failure` (inf if not within `horizon_s`). Section 6.5's cubic
    extrapolation (fig. 6.14), with the bootstrap band beyond the thesis."""
    scale = max(float(t[-1] - t[0]), 1e-9)
    x = (t - t_now) / scale
    c = np.polyfit(x, y, degree)
    res = y - np.polyval(c, x)
    ys = [y[:, None]]
    if n_boot > 0:
        ys.append(np.polyval(c, x)[:, None] + rng.choice(res, size=(len(y), n_boot)))
    Y = np.concatenate(ys, axis=1)
    C = np.polyfit(x, Y, degree)                                   # (degree + 1, 1 + B)
    grid = np.linspace(0.0, horizon_s / scale, 4000)
    V = np.vander(grid, degree + 1) @ C                            # (4000, 1 + B)
    below = V < failure
    first = np.where(below.any(axis=0), below.argmax(axis=0), -1)
    toe = np.where(first >= 0, t_now + grid[np.maximum(first, 0)] * scale, np.inf)
    return toe, C[:, 0], scale


def thesis_predict(t: np.ndarray, ci: np.ndarray, threshold: float = THRESHOLD,
                   warning: float = WARNING, failure: float = FAILURE, degree: int = 3,
                   n_boot: int = N_BOOT, seed: int = 0,
                   t_pred_s: float | None = None) -> ThesisResult | None:
    """The thesis' prediction: cubic fit between the threshold and warning crossings,
    extrapolated to `failure`. Made at the warning crossing (or at `t_pred_s` >= it,
    fitting the points from the threshold crossing up to then). None before a warning."""
    t = np.asarray(t, dtype=float)
    ci = np.asarray(ci, dtype=float)
    t_thr = first_below(t, ci, threshold)
    if math.isnan(t_thr):
        return None
    t_warn = first_below(t, ci, warning, after=t_thr)
    if math.isnan(t_warn):
        return ThesisResult(t_thr, math.nan, [], 1.0, None)
    t_now = t_warn if t_pred_s is None else max(t_warn, float(t_pred_s))
    m = (t >= t_thr) & (t <= t_now + 1e-9)
    if m.sum() < degree + 2:
        return ThesisResult(t_thr, t_warn, [], 1.0, None)
    rng = np.random.default_rng(seed)
    horizon = 5.0 * max(t_now - t_thr, 1.0) + 60.0
    toe, c, scale = _cubic_toe(t[m], ci[m], t_now, failure, degree, n_boot, rng, horizon)
    samples = toe[1:] if n_boot > 0 else toe
    res = ThesisResult(t_thr, t_warn, c.tolist(), scale, Prediction(t_now, samples))
    res.point_toe_s = float(toe[0])  # the fit of the data itself (bootstrap: the band)
    return res


def thesis_profile(t: np.ndarray, ci: np.ndarray, n_boot: int = N_BOOT, seed: int = 0,
                   threshold: float = THRESHOLD, warning: float = WARNING,
                   failure: float = FAILURE) -> list[Prediction]:
    """The thesis' prediction re-made every period from the warning on (fit from the
    threshold crossing to the present)."""
    first = thesis_predict(t, ci, threshold=threshold, warning=warning, failure=failure,
                           n_boot=0)
    if first is None or first.prediction is None:
        return []
    out = []
    for k, tp in enumerate(t[t >= first.t_warning_s - 1e-9]):
        r = thesis_predict(t, ci, threshold=threshold, warning=warning, failure=failure,
                           n_boot=n_boot, seed=seed + k, t_pred_s=float(tp))
        if r is not None and r.prediction is not None:
            out.append(r.prediction)
    return out
