"""The fused predictor (beyond the thesis): a backlash estimate fused from several HUMS
indexes, its warning, and failure-time predictions with a band.

Every index that backlash drives (lost motion, Ci on the first 15 harmonics (eq. 6.6),
harmonic distortion of the current spectrum (eq. 6.3), reversal dead time) is mapped to
a backlash-equivalent b (um) through the noise-free H4 sweep (the `Calibration`, built by
`bench.hums.calibration`), and the estimates are fused with inverse-variance weights
measured on healthy noisy runs. A warning is raised when the causal 3-period median of
the fused b exceeds a level set from healthy runs. From then on, every period, an
exponential degradation model b(t) = K e^(s t) is fitted to ln b by weighted least
squares on the points above the noise floor, and the failure time is where it reaches
b_fail, the backlash at which the calibration's Ci crosses 0.56 (the thesis' failure
level, section 6.5); a residual bootstrap (and +-5 % on b_fail) gives the band.

The model family (exponential growth) is the one the plant's schedule uses: a best case
for the model form; a real actuator's wear law has to be identified from fleet data.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums.rul import N_BOOT, Prediction

FEATURES = ("lost_motion", "ci_harmonic", "distortion", "dead_time")
"""Indexes fused into the backlash estimate. The closed-loop mean position error was
tried too (`feature_values(..., "mean_error")`) and left out: its map to backlash, taken
along the sweep's diagonal, is biased by friction growth and preload (the position error
grows with friction alone), and fusing it moved the warning of the R1 run from 66.5 s to
75 s and shortened the prognostic horizon from 44 % to 19 % of life."""


@dataclass
class Calibration:
    """Feature -> backlash maps (noise-free H4 sweep), noise levels (healthy noisy runs),
    fusion weights, warning level and failure backlash."""
    backlash_um: list[float]
    curves: dict[str, list[float]]       # feature value at each backlash of the sweep
    ci_curve: list[float]                # per-period Ci of the sweep (failure map)
    sigma_um: dict[str, float]           # noise of each feature's backlash estimate
    offset_um: dict[str, float]          # healthy bias of each estimate (removed)
    weights: dict[str, float]
    warn_um: float
    """The detection level (um): the causal 3-period median of the fused estimate above it
    is backlash measurably above every healthy calibration run (1.5 x their largest, >= 6
    sigma): the fused predictor's warning, from which it predicts the RUL. Not a level of
    wear: the wear levels are `backlash_at_ci` of the thesis' Ci levels."""
    floor_um: float
    fail_um: float
    lm_model: list[float] = field(default_factory=list)   # LM = l0 + kappa I_f + k_b b
    healthy_fused_um: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    def backlash_at_ci(self, level: float) -> float:
        """The backlash (um) at which the calibration sweep's Ci crosses `level`: the
        thesis' Ci levels (section 6.5) in backlash, so that the fused estimate is graded
        on the scale Ci is (0.93 -> ~18 um, 0.80 -> ~40 um, 0.56 -> b_fail ~90 um on the
        bench's plant)."""
        return crossing_backlash(self.backlash_um, self.ci_curve, level)


def crossing_backlash(b_um: list[float], ci: list[float], level: float) -> float:
    """The backlash at which a sweep's Ci (falling with backlash) first crosses `level`,
    linearly interpolated (the last segment extrapolated when it never does)."""
    b = np.asarray(b_um, dtype=float)
    c = np.asarray(ci, dtype=float)
    k = np.flatnonzero(c < level)
    if not len(k):
        return float(b[-1] + (level - c[-1]) * (b[-1] - b[-2]) / (c[-1] - c[-2]))
    j = int(k[0])
    if j == 0:
        return float(b[0])
    return float(b[j - 1] + (level - c[j - 1]) * (b[j] - b[j - 1]) / (c[j] - c[j - 1]))


def feature_values(table: dict[str, np.ndarray], name: str) -> np.ndarray:
    """The raw value of feature `name` per period from an `as_table` dict."""
    if name == "lost_motion":
        return table["lost_motion_m"] * 1e6
    if name == "ci_harmonic":
        return 1.0 - table["ci_harmonic"]
    if name == "distortion":
        return table["harmonic_distortion"] - table["nominal_harmonic_distortion"]
    if name == "dead_time":
        return table["dead_time_s"] * 1e3
    if name == "mean_error":
        return table["mean_error_m"] * 1e6
    raise BenchError(f"unknown feature {name!r}")


def _to_backlash(values: np.ndarray, curve: list[float], b_um: list[float]) -> np.ndarray:
    """Invert a monotone feature(b) curve, linear beyond both ends (no clipping, so the
    noise of a healthy estimate around 0 is measured, not folded)."""
    c = np.maximum.accumulate(np.asarray(curve, dtype=float))
    b = np.asarray(b_um, dtype=float)
    values = np.asarray(values, dtype=float)
    out = np.interp(values, c, b)
    for hi, (i0, i1) in ((False, (0, 1)), (True, (-2, -1))):
        m = values > c[-1] if hi else values < c[0]
        if m.any() and c[i1] > c[i0]:
            out[m] = b[i1 if hi else i0] + (values[m] - c[i1 if hi else i0]) * (
                b[i1] - b[i0]) / (c[i1] - c[i0])
    return out


def estimates(table: dict[str, np.ndarray], cal: Calibration) -> dict[str, np.ndarray]:
    """Backlash estimate (um) of each available feature, healthy offset removed."""
    out = {}
    for f in FEATURES:
        if f not in cal.curves:
            continue
        try:
            v = feature_values(table, f)
        except KeyError:
            continue
        if not np.isfinite(v).any():
            continue
        if f == "lost_motion" and cal.lm_model:
            l0, kappa, kb = cal.lm_model
            fc = table.get("friction_current_a")
            fc = np.nan_to_num(fc, nan=0.0) if fc is not None else np.zeros_like(v)
            out[f] = (v - l0 - kappa * fc) / kb - cal.offset_um.get(f, 0.0)
        else:
            out[f] = _to_backlash(v, cal.curves[f], cal.backlash_um) \
                - cal.offset_um.get(f, 0.0)
    return out


def fused_backlash(table: dict[str, np.ndarray], cal: Calibration) -> np.ndarray:
    """Inverse-variance fusion of the per-feature backlash estimates (um); features whose
    signals a log lacks (NaN) drop out and the others carry the estimate."""
    est = estimates(table, cal)
    if not est:
        raise BenchError("no HUMS feature to fuse: the log needs current_a, position_m "
                         "and ideally motor_angle_rad and motor_speed_rad_s")
    num = np.zeros(len(next(iter(est.values()))))
    den = np.zeros_like(num)
    for f, b in est.items():
        w = cal.weights.get(f, 0.0)
        ok = np.isfinite(b)
        num[ok] += w * b[ok]
        den[ok] += w
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def causal_median(x: np.ndarray, n: int = 3) -> np.ndarray:
    """Median of the last `n` values at each point (what an online monitor can compute)."""
    out = np.empty_like(x)
    for k in range(len(x)):
        out[k] = np.nanmedian(x[max(0, k - n + 1):k + 1])
    return out


@dataclass
class FusedResult:
    """The fused estimate, its smoothed copy, the warning time and the predictions."""
    b_um: np.ndarray
    b_smooth_um: np.ndarray
    t_warning_s: float
    predictions: list[Prediction]


class FusedPredictor:
    """Warning and failure-time predictions from the fused backlash estimate."""

    def __init__(self, cal: Calibration, n_boot: int = N_BOOT, seed: int = 0,
                 min_points: int = 6, model_sigma: float = 0.03) -> None:
        self.cal = cal
        self.n_boot = n_boot
        self.seed = seed
        self.min_points = min_points
        self.model_sigma = model_sigma

    def run(self, t: np.ndarray, table: dict[str, np.ndarray]) -> FusedResult:
        b = fused_backlash(table, self.cal)
        bs = causal_median(b, 3)
        warn = np.flatnonzero(bs > self.cal.warn_um)
        t_w = float(t[warn[0]]) if len(warn) else math.nan
        preds: list[Prediction] = []
        if len(warn):
            for k in range(int(warn[0]), len(t)):
                p = self.predict(t[:k + 1], b[:k + 1], k)
                if p is not None:
                    preds.append(p)
        return FusedResult(b, bs, t_w, preds)

    def predict(self, t: np.ndarray, b: np.ndarray, k: int = 0) -> Prediction | None:
        """Exponential model ln b = a + s t fitted (weighted) to the points above the
        noise floor; failure where it reaches b_fail; residual bootstrap band."""
        cal = self.cal
        m = np.isfinite(b) & (b > cal.floor_um)
        if m.sum() < self.min_points:
            return None
        x, bb = t[m] - t[-1], b[m]
        y = np.log(bb)
        w2 = 1.0 / ((fused_sigma(cal) / bb) ** 2 + self.model_sigma ** 2)
        a0, s0 = _wls_line(x, y, w2)
        res = (y - a0 - s0 * x) * np.sqrt(w2)
        rng = np.random.default_rng(self.seed + 7919 * k)
        n, B = len(y), self.n_boot
        # residual bootstrap, and a random start of the fitted window per replicate: the
        # spread over windows is the model-form error a pure residual bootstrap misses
        Y = (a0 + s0 * x)[:, None] + rng.choice(res, size=(n, B)) / np.sqrt(w2)[:, None]
        start = rng.integers(0, n - self.min_points + 1, size=B)
        W = w2[:, None] * (np.arange(n)[:, None] >= start[None, :])
        C0, C1 = _wls_line(x[:, None], Y, W)
        lf = np.log(cal.fail_um) + np.log(rng.uniform(0.95, 1.05, B))
        with np.errstate(divide="ignore", invalid="ignore"):
            toe = np.where(C1 > 0, t[-1] + (lf - C0) / C1, np.inf)
        toe = np.maximum(toe, t[-1])        # already past b_fail: failure now
        return Prediction(float(t[-1]), toe)


def _wls_line(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[Any, Any]:
    """Weighted least-squares line y = a + s x, column-wise (closed form)."""
    sw = np.sum(w, axis=0)
    sx = np.sum(w * x, axis=0)
    sy = np.sum(w * y, axis=0)
    sxx = np.sum(w * x * x, axis=0)
    sxy = np.sum(w * x * y, axis=0)
    det = sw * sxx - sx * sx
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (sw * sxy - sx * sy) / det
        a = (sy - s * sx) / sw
    return a, s


def fused_sigma(cal: Calibration) -> float:
    """Standard deviation (um) of the inverse-variance fused estimate."""
    den = sum(cal.weights.values())
    return math.sqrt(1.0 / den) if den > 0 else math.inf
