"""Prognosis: the thesis' RUL algorithm (section 6.5, rows R1-R2) and a fused predictor
with an uncertainty band, scored on a run-to-failure campaign.

The run: the H4 sine (+-0.5 mm, 2 Hz) for `schedule.duration_s` with the plant's RUL
schedule (preload falling linearly to 0 at `preload_zero_frac` of the run, backlash and
friction growing exponentially to 100 um and x4). The HUMS computes its indexes once per
command period (0.5 s) against the monitoring model; each value is time-stamped at the
END of its period, the moment an online monitor has it.

Failure (the thesis' definition): the current fidelity coefficient Ci reaches 0.56. The
true time of failure of a run is taken on its noise-free twin (same schedule, no sensor
noise): the end of the first period whose Ci is below 0.56.

Thesis algorithm (`thesis_predict`): once Ci falls below the threshold 0.93 the points
are stored; when it falls below the warning level 0.80, a cubic is fitted to Ci(t) over
the points between the two crossings and extrapolated to 0.56: RUL = t(0.56) - t(warning).
Its band here comes from a residual bootstrap of the cubic fit.

Fused predictor (`FusedPredictor`, beyond the thesis): every index that backlash drives
(lost motion, Ci on the first 15 harmonics, harmonic distortion, reversal dead time) is
mapped to a backlash-equivalent b (um) through the noise-free H4 sweep (the calibration),
and the estimates are fused with inverse-variance weights measured on healthy noisy runs.
A warning is raised when the causal 3-period median of the fused b exceeds a level set
from healthy runs. From then on, every period, an exponential degradation model
b(t) = K e^(s t) is fitted to ln b by weighted least squares on the points above the
noise floor, and the failure time is where it reaches b_fail, the backlash at which the
calibration's Ci crosses 0.56; a residual bootstrap (and +-5 % on b_fail) gives the band.

The model family (exponential growth) is the one the plant's schedule uses: a best case
for the model form; a real actuator's wear law has to be identified from fleet data.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums import indexes as I
from bench.hums import monitor as M
from bench.hums.table import Row
from plant_rt.params import PlantParams

THRESHOLD, WARNING, FAILURE = 0.93, 0.80, 0.56
THESIS_RUL_S, THESIS_T_PRED_S = 13.5, 118.0
THESIS_BACKLASH_UM, THESIS_FRICTION = 85.0, 3.9
FEATURES = ("lost_motion", "ci_harmonic", "distortion", "dead_time")
"""Indexes fused into the backlash estimate. The closed-loop mean position error was
tried too (`feature_values(..., "mean_error")`) and left out: its map to backlash, taken
along the sweep's diagonal, is biased by friction growth and preload (the position error
grows with friction alone), and fusing it moved the warning of the R1 run from 66.5 s to
75 s and shortened the prognostic horizon from 44 % to 19 % of life."""
N_BOOT = 200
CALIBRATION_VERSION = 3     # part of the report's cache key: bump when calibrate() changes


# --- one run: per-period indexes with truth --------------------------------------------------

@dataclass
class RunRecord:
    """Per-period indexes of one run, time-stamped at period ends, plus simulation truth
    at those times (never used by the predictors, only to score them)."""
    t_s: np.ndarray
    table: dict[str, np.ndarray]
    truth: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def col(self, name: str) -> np.ndarray:
        return self.table[name]


def record_from_trace(real: Any, kp: float, mparams: M.MonitorParams | None = None,
                      period_s: float | None = None) -> RunRecord:
    """Per-period indexes of a trace (measured columns only) against the monitor."""
    meas = real.measured()
    nom = M.nominal_for(meas, kp, mparams)
    rows = list(I.period_indexes(meas, nom, period_s))
    if not rows:
        raise BenchError("the trace is shorter than one command period")
    tab = I.as_table(rows)
    per = rows[0].t_end_s - rows[0].t_start_s
    t_end = tab["t_start_s"] + per
    truth: dict[str, np.ndarray] = {}
    idx = np.clip(np.searchsorted(real.t, t_end) - 1, 0, len(real) - 1)
    for k in ("backlash_m", "friction_scale", "preload_n"):
        if k in real:
            truth[k] = real[k][idx]
    return RunRecord(t_end, tab, truth, {"period_s": per,
                                         "duration_s": float(real.t[-1] + real.dt)})


def simulate_record(params: PlantParams, kp: float, duration_s: float | None = None,
                    progress: bool = False) -> RunRecord:
    """Run the RUL sine with `params` (schedule included) and index it per period."""
    from bench.harness import simulate
    from bench.profiles import make_profile
    dur = duration_s if duration_s is not None else (
        params.schedule.duration_s if params.schedule.kind == "rul" else 120.0)
    prof = make_profile("sine", duration_s=dur)
    real = simulate(prof, params, progress=progress)
    if not real.meta.get("complete", True):
        raise BenchError("the plant stopped integrating (non-finite state) during the run")
    rec = record_from_trace(real, kp, M.MonitorParams.from_plant(params))
    rec.meta["params"] = params.to_json()
    return rec


def true_failure_time(t: np.ndarray, ci: np.ndarray, failure: float = FAILURE) -> float:
    """End time of the first period with Ci below `failure` (NaN if never)."""
    hit = np.flatnonzero(np.asarray(ci) < failure)
    return float(t[hit[0]]) if len(hit) else math.nan


# --- the thesis' algorithm -------------------------------------------------------------------

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
    t_threshold_s: float
    t_warning_s: float
    coeffs: list[float]               # cubic in (t - t_pred) / scale, highest first
    scale_s: float
    prediction: Prediction | None
    point_toe_s: float = math.nan     # failure time of the cubic fitted to the data

    @property
    def rul_s(self) -> float:
        return self.prediction.rul_s if self.prediction else math.nan


def _first_below(t: np.ndarray, y: np.ndarray, level: float, after: float = -math.inf
                 ) -> float:
    hit = np.flatnonzero((np.asarray(y) < level) & (np.asarray(t) >= after))
    return float(t[hit[0]]) if len(hit) else math.nan


def _cubic_toe(t: np.ndarray, y: np.ndarray, t_now: float, failure: float, degree: int,
               n_boot: int, rng: np.random.Generator, horizon_s: float
               ) -> tuple[np.ndarray, np.ndarray, float]:
    """Fit a polynomial of `degree` to y(t), bootstrap its residuals; the first time after
    t_now each fit reaches `failure` (inf if not within `horizon_s`)."""
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
    t_thr = _first_below(t, ci, threshold)
    if math.isnan(t_thr):
        return None
    t_warn = _first_below(t, ci, warning, after=t_thr)
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
                   **levels: float) -> list[Prediction]:
    """The thesis' prediction re-made every period from the warning on (fit from the
    threshold crossing to the present)."""
    first = thesis_predict(t, ci, n_boot=0, **levels)
    if first is None or first.prediction is None:
        return []
    out = []
    for k, tp in enumerate(t[t >= first.t_warning_s - 1e-9]):
        r = thesis_predict(t, ci, n_boot=n_boot, seed=seed + k, t_pred_s=float(tp), **levels)
        if r is not None and r.prediction is not None:
            out.append(r.prediction)
    return out


# --- calibration and the fused predictor ---------------------------------------------------

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
    floor_um: float
    fail_um: float
    lm_model: list[float] = field(default_factory=list)   # LM = l0 + kappa I_f + k_b b
    healthy_fused_um: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


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


def _causal_median(x: np.ndarray, n: int = 3) -> np.ndarray:
    out = np.empty_like(x)
    for k in range(len(x)):
        out[k] = np.nanmedian(x[max(0, k - n + 1):k + 1])
    return out


@dataclass
class FusedResult:
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
        bs = _causal_median(b, 3)
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
        w2 = 1.0 / ((_fused_sigma(cal) / bb) ** 2 + self.model_sigma ** 2)
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


def _fused_sigma(cal: Calibration) -> float:
    den = sum(cal.weights.values())
    return math.sqrt(1.0 / den) if den > 0 else math.inf


def _calib_point(job: tuple[float, float, str, float | None]) -> dict[str, Any]:
    """Worker: noise-free H4 sine (2 s) at degradation d (or, with `friction`, at zero
    backlash and that friction scale), per-period features of periods 2-4 averaged (the
    first period holds the start-up transient)."""
    from bench.harness import simulate
    from bench.hums.sweep import degraded
    from bench.profiles import make_profile
    d, kp, pj, friction = job
    base = PlantParams.from_json(pj)
    p = degraded(base, d, False, 1)
    if friction is not None:
        p = p.with_dict({"effects.backlash_m": 0.0, "effects.friction_scale": friction})
    real = simulate(make_profile("sine"), p)
    rec = record_from_trace(real, kp, M.MonitorParams.from_plant(base))
    sl = slice(1, None)
    out = {"d": d, "friction": friction, "ci": float(np.mean(rec.table["ci"][sl])),
           "b_um": float(p.effects.backlash_m * 1e6),
           "friction_current_a": float(np.mean(rec.table["friction_current_a"][sl]))}
    for f in FEATURES:
        out[f] = float(np.mean(feature_values(rec.table, f)[sl]))
    return out


def _healthy_params(base: PlantParams, rng: np.random.Generator, seed: int) -> PlantParams:
    """A healthy actuator: no backlash, friction within +-10 % of nominal (spread between
    units), a preload of 0-3 kN held constant, sensor noise on."""
    return base.with_dict({"schedule.kind": "none", "effects.backlash_m": 0.0,
                           "effects.friction_scale": float(rng.uniform(0.9, 1.1)),
                           "effects.preload_n": float(rng.choice([0.0, rng.uniform(1e3, 3e3)])),
                           "sensors.noise": True, "sensors.noise_seed": int(seed)})


def _healthy_record(job: tuple[str, float, float]) -> RunRecord:
    pj, kp, dur = job
    return simulate_record(PlantParams.from_json(pj), kp, dur)


def calibrate(base: PlantParams | None = None, kp: float | None = None,
              n_healthy: int = 4, healthy_s: float = 60.0, seed: int = 12345,
              workers: int | None = None, progress: bool = True) -> Calibration:
    """Build the fusion's calibration: the noise-free H4 sweep (11 points) gives each
    feature's map to backlash and b_fail (where its Ci crosses 0.56); `n_healthy` noisy
    healthy runs give each estimate's noise, the weights and the warning level."""
    from bench.hums.pool import run_all
    base = base or PlantParams()
    if kp is None:
        kp = M.fitted(base)[0].gain_rad_s_per_m
    pj = base.to_json()
    rng = np.random.default_rng(seed)
    hjobs = [(_healthy_params(base, rng, seed + k).to_json(), kp, healthy_s)
             for k in range(n_healthy)]
    levels = np.linspace(0.0, 1.0, 11)
    res = run_all(_any_job, [("h", j) for j in hjobs]
                  + [("c", (float(d), kp, pj, None)) for d in levels]
                  + [("c", (0.0, kp, pj, fr)) for fr in (2.0, 3.0, 4.0)], workers, progress,
                  desc="hums calibration", unit="run")
    allpts = [r for r in res if isinstance(r, dict)]
    pts = sorted((r for r in allpts if r["friction"] is None), key=lambda r: r["d"])
    healthy = [r for r in res if isinstance(r, RunRecord)]
    b_um = [100.0 * p["d"] for p in pts]
    curves = {f: [p[f] for p in pts] for f in FEATURES}
    ci_curve = [p["ci"] for p in pts]
    # lost motion = l0 + kappa I_f + k_b b: backlash plus the elastic give of the contacts
    # under the friction force (I_f, friction current), fitted on the diagonal sweep and
    # the zero-backlash friction points (which separate the two)
    A = np.array([[1.0, r["friction_current_a"], r["b_um"]] for r in allpts])
    lm = np.array([r["lost_motion"] for r in allpts])
    lm_model = np.linalg.lstsq(A, lm, rcond=None)[0].tolist()
    cal = Calibration(b_um, curves, ci_curve, {}, {}, {}, 0.0, 0.0,
                      _fail_backlash(b_um, ci_curve), lm_model)
    # noise of each estimate on healthy runs (skip the first period: start-up)
    sig, off = {}, {}
    for f in FEATURES:
        vals = np.concatenate([estimates(r.table, cal).get(f, np.array([]))[1:]
                               for r in healthy]) if healthy else np.array([])
        vals = vals[np.isfinite(vals)]
        if len(vals) < 10:
            continue
        off[f] = float(np.median(vals))
        sig[f] = float(max(np.std(vals), 1e-3))
    cal.sigma_um, cal.offset_um = sig, off
    cal.weights = {f: 1.0 / s ** 2 for f, s in sig.items()}
    hf = np.concatenate([_causal_median(fused_backlash(r.table, cal), 3)[1:]
                         for r in healthy]) if healthy else np.array([0.0])
    s_f = _fused_sigma(cal)
    # warning: above every healthy 3-period median seen, with margin, and >= 6 sigma
    cal.warn_um = float(max(1.5 * np.max(hf), 6.0 * s_f, 0.5))
    cal.floor_um = float(max(5.0 * s_f, 0.5))
    cal.healthy_fused_um = hf.tolist()
    return cal


def _any_job(job: tuple[str, Any]) -> Any:
    kind, arg = job
    if kind == "c":
        return _calib_point(arg)
    if kind == "h":
        return _healthy_record(arg)
    if kind == "run":
        return _campaign_run(arg)
    raise BenchError(f"unknown job {kind!r}")


def _fail_backlash(b_um: list[float], ci: list[float], failure: float = FAILURE) -> float:
    b = np.asarray(b_um)
    c = np.asarray(ci)
    k = np.flatnonzero(c < failure)
    if not len(k):
        # extrapolate the last segment
        return float(b[-1] + (failure - c[-1]) * (b[-1] - b[-2]) / (c[-1] - c[-2]))
    j = int(k[0])
    if j == 0:
        return float(b[0])
    return float(b[j - 1] + (failure - c[j - 1]) * (b[j] - b[j - 1]) / (c[j] - c[j - 1]))


# --- the thesis' run (R1-R2) ---------------------------------------------------------------------

@dataclass
class RulResult:
    noisy: bool
    record: RunRecord
    truth_record: RunRecord
    t_failure_s: float
    thesis: ThesisResult | None
    thesis_harmonic: ThesisResult | None
    fused: FusedResult | None
    cal: Calibration | None
    gain: float
    elapsed_s: float
    machine: str = ""


def run_rul(params: PlantParams | None = None, noise: bool = False, fused: bool = True,
            workers: int | None = None, progress: bool = True,
            cal: Calibration | None = None) -> RulResult:
    """R1-R2: the 120 s run with the thesis' schedule, its indexes, the thesis' prediction,
    and (with `fused`) the fused prediction with its band."""
    from bench import machine_description
    from bench.hums.pool import run_all
    t0 = time.perf_counter()
    base = params or PlantParams()
    kp = M.fitted(base)[0].gain_rad_s_per_m
    p = base.with_dict({"schedule.kind": "rul", "sensors.noise": noise})
    twin = p.with_dict({"sensors.noise": False})
    jobs = [("r", (p.to_json(), kp))]
    if noise:
        jobs.append(("r", (twin.to_json(), kp)))
    recs = run_all(_rul_job, jobs, workers, progress, desc="hums rul", unit="run")
    rec = recs[0]
    truth = recs[1] if noise else rec
    t_f = true_failure_time(truth.t_s, truth.table["ci"])
    th = thesis_predict(rec.t_s, rec.table["ci"])
    thh = thesis_predict(rec.t_s, rec.table["ci_harmonic"])
    fr = None
    if fused:
        cal = cal or calibrate(base, kp, workers=workers, progress=progress)
        fr = FusedPredictor(cal).run(rec.t_s, rec.table)
    return RulResult(noise, rec, truth, t_f, th, thh, fr, cal, kp,
                     time.perf_counter() - t0, machine_description())


def _rul_job(job: tuple[str, tuple[str, float]]) -> RunRecord:
    _, (pj, kp) = job
    return simulate_record(PlantParams.from_json(pj), kp)


def rows(res: RulResult) -> list[Row]:
    """Rows R1-R2 (and the fused predictor beyond them)."""
    rec, tr = res.record, res.truth_record
    t, ci = tr.t_s, tr.table["ci"]
    T = rec.meta["duration_s"]
    first = (t > 2.0) & (t <= T / 2)
    base = float(np.median(ci[(t > 0.5) & (t <= 5.0)]))
    flat = float(np.max(np.abs(ci[first] - base)))
    slopes = []
    for a, b in ((0.6, 0.7), (0.8, 0.9), (0.9, 1.0)):
        m = (t > a * T) & (t <= b * T)
        slopes.append(float(np.polyfit(t[m], ci[m], 1)[0]))
    out = [
        Row("R1", "Ci in the first half: max |Ci - Ci(0.5-5 s)| (noise-free)", "-",
            "flat", round(flat, 4)),
        Row("R1", "Ci slope at 60-70 / 80-90 / 90-100 % of the run", "1/s",
            "falling ever faster", " / ".join(f"{s:.4f}" for s in slopes)),
        Row("R1", "preload reaches 0 / Ci first below 0.99", "s", "first half / after it",
            f"{_preload_zero(rec):.1f} / {_first_below(t, ci, 0.99):.1f}"),
    ]
    th = res.thesis
    tag = " (noise)" if res.noisy else ""
    if th is not None and th.prediction is not None:
        pr = th.prediction
        lo, hi = pr.band()
        t_w = th.t_warning_s
        b_w, f_w = _truth_at(rec, t_w)
        true_rul = res.t_failure_s - t_w
        point = th.point_toe_s
        out += [
            Row("R2", f"time of the warning (Ci < 0.80){tag}", "s", THESIS_T_PRED_S,
                round(t_w, 1), _why_warn_time(t_w, b_w)),
            Row("R2", "share of life at the warning (warning time / true failure time)", "%",
                90.0, round(100 * t_w / res.t_failure_s, 1)),
            Row("R2", f"predicted RUL at the warning (cubic, threshold 0.93 -> warning)"
                f"{tag}", "s", THESIS_RUL_S, round(point - t_w, 2),
                _why_rul(point - t_w, true_rul, th.t_threshold_s if res.noisy else None)),
            Row("R2", "bootstrap 90 % band of that RUL", "s", "none given",
                f"{lo - t_w:.2f} .. {hi - t_w:.2f}"),
            Row("R2", "true RUL at the warning (noise-free Ci reaches 0.56)", "s",
                "not given", round(true_rul, 2)),
            Row("R2", "true time of failure (noise-free Ci < 0.56)", "s",
                "not given (prediction 131.5)", round(res.t_failure_s, 1)),
            Row("R2", "backlash at the warning", "um", THESIS_BACKLASH_UM,
                round(b_w * 1e6, 1), _why_state(b_w) + (
                    " With noise, plain Ci reads ~10 % low from the start, so it reaches "
                    "0.80 earlier still." if res.noisy and _why_state(b_w) else "")),
            Row("R2", "friction scale at the warning", "-", THESIS_FRICTION, round(f_w, 2),
                "" if abs(f_w / THESIS_FRICTION - 1) <= 0.1 else
                "same cause as the backlash row: the warning comes earlier in the schedule"),
        ]
        b_t, f_t = _truth_at(rec, THESIS_T_PRED_S)
        ci_t = float(np.interp(THESIS_T_PRED_S, t, ci))
        out.append(Row("R2", "at the thesis' 118 s: backlash / friction / noise-free Ci",
                       "um / - / -", "85 / 3.9 / 0.80",
                       f"{b_t * 1e6:.1f} / {f_t:.2f} / {ci_t:.3f}"))
    else:
        out.append(Row("R2", f"warning (Ci < 0.80) reached{tag}", "-", "yes", False,
                       "Ci never fell below the warning level in this run"))
    if res.fused is not None and res.cal is not None:
        fr = res.fused
        t_f = res.t_failure_s
        sc = score_run(fr.predictions, fr.t_warning_s, t_f)
        th_sc = score_run(thesis_profile(rec.t_s, rec.table["ci"], n_boot=100),
                          th.t_warning_s if th else math.nan, t_f)
        out += [
            Row("R2+", "fused: warning time / share of life", "s / %", "-",
                f"{fr.t_warning_s:.1f} / {100 * fr.t_warning_s / t_f:.1f}"),
            Row("R2+", "prognostic horizon / life (progpy; >= half the samples within "
                "+-20 % of the true RUL), fused ; thesis cubic re-fitted each period",
                "%", "-", f"{100 * sc['ph_life_frac']:.0f} ; {100 * th_sc['ph_life_frac']:.0f}"),
            Row("R2+", "horizon from which every later prediction (to 95 % of life) meets "
                "it / life, fused ; thesis", "%", "-",
                f"{100 * sc['stable_ph_life_frac']:.0f} ; "
                f"{100 * th_sc['stable_ph_life_frac']:.0f}"),
            Row("R2+", "alpha-lambda (alpha 0.2) met at 50 / 70 / 90 % of life, fused ; "
                "thesis", "-", "-",
                " / ".join("yes" if sc[f"alpha_lambda_{k}"] else "no"
                           for k in ("0.5", "0.7", "0.9")) + " ; " +
                " / ".join("yes" if th_sc[f"alpha_lambda_{k}"] else "no"
                           for k in ("0.5", "0.7", "0.9"))),
        ]
        p118 = _at(fr.predictions, THESIS_T_PRED_S)
        if p118 is not None:
            lo, hi = p118.band()
            out.append(Row("R2+", "fused at 118 s: RUL median [90 % band] vs true", "s", "-",
                           f"{p118.rul_s:.2f} [{lo - 118:.2f}, {hi - 118:.2f}] vs "
                           f"{res.t_failure_s - 118:.2f}"))
    return out


def _preload_zero(rec: RunRecord) -> float:
    pre = rec.truth.get("preload_n")
    if pre is None:
        return math.nan
    k = np.flatnonzero(pre <= 0)
    return float(rec.t_s[k[0]]) if len(k) else math.nan


def _truth_at(rec: RunRecord, t: float) -> tuple[float, float]:
    if "backlash_m" not in rec.truth or not math.isfinite(t):
        return math.nan, math.nan
    return (float(np.interp(t, rec.t_s, rec.truth["backlash_m"])),
            float(np.interp(t, rec.t_s, rec.truth["friction_scale"])))


def _why_warn_time(t_w: float, b_w: float) -> str:
    if abs(t_w / THESIS_T_PRED_S - 1) <= 0.1:
        return ""
    return "see the backlash row"


def _why_rul(rul: float, true_rul: float, t_threshold: float | None = None) -> str:
    if abs(rul / THESIS_RUL_S - 1) <= 0.1:
        return ""
    if t_threshold is not None and t_threshold < 5.0:
        return (f"sensor noise pulls plain Ci below the 0.93 threshold from the first period "
                f"(t = {t_threshold:.1f} s), so the cubic is fitted from t = 0 and "
                f"extrapolates badly; this run's true RUL at the warning is {true_rul:.1f} s")
    return (f"the warning comes at another point of the schedule (backlash row); judged "
            f"against this run's true RUL of {true_rul:.1f} s instead")


def _why_state(b_w: float) -> str:
    if abs(b_w * 1e6 / THESIS_BACKLASH_UM - 1) <= 0.1:
        return ""
    return ("in the thesis Ci reaches the 0.80 warning only at 85 um and x3.9, a state at "
            "which its own H4 sweep (46 % fall at 100 um, x4) puts near 0.6; in the project "
            "the same state gives the same Ci in the sweep and in the run (~0.57), so Ci "
            "passes 0.80 earlier in the schedule. The thesis' RUL run must differ from its "
            "sweep in a way it does not state (command, noise or friction growth).")


def _first_good(preds: list[Prediction], t_f: float, alpha: float = 0.2) -> float:
    for p in preds:
        lo, hi = p.band()
        true_rul = t_f - p.t_pred_s
        if true_rul <= 0:
            break
        if lo <= t_f <= hi and abs(p.rul_s - true_rul) <= alpha * true_rul:
            return p.t_pred_s
    return math.nan


def _at(preds: list[Prediction], t: float) -> Prediction | None:
    best = None
    for p in preds:
        if p.t_pred_s <= t + 1e-9:
            best = p
    return best


# --- the campaign ------------------------------------------------------------------------------

CAMPAIGN_RANGES = {
    "schedule.duration_s": (90.0, 150.0),
    "schedule.backlash_growth": (6.0, 14.0),
    "schedule.friction_growth": (1.0, 3.0),
    "schedule.preload_start_n": (1000.0, 3000.0),
    "schedule.preload_zero_frac": (0.35, 0.65),
}


def campaign_params(base: PlantParams, rng: np.random.Generator, seed: int) -> PlantParams:
    """One run-to-failure actuator: every CAMPAIGN_RANGES field drawn uniformly, noise on."""
    vals: dict[str, Any] = {k: float(rng.uniform(*r)) for k, r in CAMPAIGN_RANGES.items()}
    vals.update({"schedule.kind": "rul", "sensors.noise": True,
                 "sensors.noise_seed": int(seed)})
    return base.with_dict(vals)


def _campaign_run(job: tuple[str, float, bool]) -> dict[str, Any]:
    pj, kp, healthy = job
    p = PlantParams.from_json(pj)
    rec = simulate_record(p, kp)
    out: dict[str, Any] = {"record": rec, "healthy": healthy}
    if not healthy:
        twin = simulate_record(p.with_dict({"sensors.noise": False}), kp)
        out["t_failure_s"] = true_failure_time(twin.t_s, twin.table["ci"])
    return out


@dataclass
class RunScore:
    index: int
    params: dict[str, float]
    t_failure_s: float
    per_method: dict[str, dict[str, Any]]


@dataclass
class CampaignResult:
    scores: list[RunScore]
    healthy_alarm: dict[str, dict[str, float]]
    summary: dict[str, dict[str, float]]
    cal: Calibration
    elapsed_s: float
    n_runs: int
    n_healthy: int
    machine: str
    example: dict[str, Any] = field(default_factory=dict)


METHODS = ("thesis", "thesis_harmonic", "fused")


def _predictions(method: str, rec: RunRecord, cal: Calibration, seed: int
                 ) -> tuple[float, list[Prediction]]:
    if method == "thesis":
        r = thesis_predict(rec.t_s, rec.table["ci"], n_boot=0)
        preds = thesis_profile(rec.t_s, rec.table["ci"], n_boot=N_BOOT // 2, seed=seed)
        return (r.t_warning_s if r else math.nan), preds
    if method == "thesis_harmonic":
        r = thesis_predict(rec.t_s, rec.table["ci_harmonic"], n_boot=0)
        preds = thesis_profile(rec.t_s, rec.table["ci_harmonic"], n_boot=N_BOOT // 2,
                               seed=seed)
        return (r.t_warning_s if r else math.nan), preds
    fr = FusedPredictor(cal, seed=seed).run(rec.t_s, rec.table)
    return fr.t_warning_s, fr.predictions


def _alarm_series(method: str, rec: RunRecord, cal: Calibration) -> np.ndarray:
    """Per-period warning state of `method` (what a healthy run must not raise)."""
    t = rec.t_s
    if method in ("thesis", "thesis_harmonic"):
        ci = rec.table["ci" if method == "thesis" else "ci_harmonic"]
        return ci < WARNING
    b = _causal_median(fused_backlash(rec.table, cal), 3)
    return np.asarray(b > cal.warn_um) & (t > 0)


def score_run(preds: list[Prediction], t_warn: float, t_f: float, alpha: float = 0.2,
              lambdas: tuple[float, ...] = (0.5, 0.7, 0.9), beta: float = 0.5
              ) -> dict[str, Any]:
    """Prognostic metrics of one run with progpy: prognostic horizon (first time at least
    `beta` of the ToE samples lie within alpha of the true RUL), alpha-lambda at fractions
    `lambdas` of the true life, and relative accuracy of the median RUL there."""
    import matplotlib
    with matplotlib.rc_context():   # importing progpy rewrites matplotlib's rcParams
        from progpy.metrics import alpha_lambda, prognostic_horizon
        from progpy.predictors import ToEPredictionProfile
        from progpy.uncertain_data import UnweightedSamples
    out: dict[str, Any] = {"t_warning_s": t_warn,
                           "warning_life_frac": t_warn / t_f if math.isfinite(t_warn) else
                           math.nan, "n_predictions": len(preds)}
    gt = {"failure": t_f}
    prof = ToEPredictionProfile()
    for p in preds:
        if p.t_pred_s >= t_f:
            break
        s = np.where(np.isfinite(p.toe_samples), p.toe_samples, 1e9)
        prof.add_prediction(p.t_pred_s, UnweightedSamples([{"failure": float(x)} for x in s]))

    def crit(tte: Any, gt_tte: dict[str, float]) -> dict[str, bool]:
        b = {k: [v * (1 - alpha), v * (1 + alpha)] for k, v in gt_tte.items()}
        pib = tte.percentage_in_bounds(b)
        return {k: pib[k] >= beta for k in pib}

    ph = prognostic_horizon(prof, crit, gt)["failure"] if len(prof) else None
    out["ph_s"] = float(ph) if ph is not None else 0.0
    out["ph_life_frac"] = out["ph_s"] / t_f
    # stable horizon: from when the criterion holds at every later prediction, up to a
    # true RUL of 5 % of life (past that, +-20 % of the RUL is below the 0.5 s period)
    ok = []
    for p in preds:
        if p.t_pred_s >= 0.95 * t_f:
            break
        lo_b, hi_b = t_f - alpha * (t_f - p.t_pred_s), t_f + alpha * (t_f - p.t_pred_s)
        s = p.toe_samples
        ok.append((p.t_pred_s, float(np.mean((s > lo_b) & (s < hi_b))) >= beta))
    stable = math.nan
    for k in range(len(ok)):
        if all(v for _, v in ok[k:]):
            stable = ok[k][0]
            break
    out["stable_ph_life_frac"] = (t_f - stable) / t_f if math.isfinite(stable) else 0.0
    for lam in lambdas:
        t_l = lam * t_f
        near = [p for p in preds if t_l - 1e-9 <= p.t_pred_s <= t_l + 0.75]
        key = f"{lam:g}"
        if not near or not len(prof):
            out[f"alpha_lambda_{key}"] = False
            out[f"ra_{key}"] = math.nan
            continue
        al = alpha_lambda(prof, gt, lambda_value=t_l - 1e-9, alpha=alpha, beta=beta)
        out[f"alpha_lambda_{key}"] = bool(al and al.get("failure"))
        p = near[0]
        true_rul = t_f - p.t_pred_s
        out[f"ra_{key}"] = 1.0 - abs(true_rul - p.rul_s) / true_rul if math.isfinite(
            p.rul_s) else 0.0
    return out


def run_campaign(n_runs: int = 20, n_healthy: int = 10, seed: int = 2024,
                 params: PlantParams | None = None, workers: int | None = None,
                 progress: bool = True, cal: Calibration | None = None) -> CampaignResult:
    """`n_runs` run-to-failure runs (randomised schedules and noise seeds, each with a
    noise-free twin for its true failure time) and `n_healthy` healthy runs (false
    alarms), scored for the thesis algorithm (on Ci and on harmonic Ci) and the fused
    predictor with progpy's metrics."""
    from bench import machine_description
    from bench.hums.pool import run_all
    if n_runs < 1:
        raise BenchError("the campaign needs at least one run-to-failure run")
    t0 = time.perf_counter()
    base = params or PlantParams()
    kp = M.fitted(base)[0].gain_rad_s_per_m
    cal = cal or calibrate(base, kp, workers=workers, progress=progress)
    rng = np.random.default_rng(seed)
    run_params = [campaign_params(base, rng, seed * 1000 + k) for k in range(n_runs)]
    healthy_params = [_healthy_params(base, rng, seed * 1000 + 500 + k).with_dict(
        {"schedule.duration_s": 120.0}) for k in range(n_healthy)]
    jobs = [("run", (p.to_json(), kp, False)) for p in run_params]
    jobs += [("run", (p.to_json(), kp, True)) for p in healthy_params]
    # longest first keeps both workers busy to the end (a failing run also runs its twin)
    cost = [120.0 if healthy else 2.0 * PlantParams.from_json(pj).schedule.duration_s
            for _, (pj, _, healthy) in jobs]
    order = sorted(range(len(jobs)), key=lambda k: -cost[k])
    got = run_all(_any_job, [jobs[k] for k in order], workers, progress,
                  desc="hums campaign", unit="run")
    results: list[Any] = [None] * len(jobs)
    for k, r in zip(order, got, strict=True):
        results[k] = r
    scores = []
    for k, (p, r) in enumerate(zip(run_params, results[:n_runs], strict=True)):
        rec, t_f = r["record"], r["t_failure_s"]
        per: dict[str, dict[str, Any]] = {}
        for mth in METHODS:
            if not math.isfinite(t_f):
                per[mth] = {"censored": True}
                continue
            t_w, preds = _predictions(mth, rec, cal, seed + k)
            per[mth] = score_run(preds, t_w, t_f)
        scores.append(RunScore(k, {n: p.get(n) for n in CAMPAIGN_RANGES}, t_f, per))
    healthy_alarm = {}
    for mth in METHODS:
        alarms = [_alarm_series(mth, r["record"], cal)[1:] for r in results[n_runs:]]
        n = sum(len(a) for a in alarms)
        healthy_alarm[mth] = {
            "period_rate": float(sum(int(a.sum()) for a in alarms) / n) if n else math.nan,
            "run_rate": float(np.mean([a.any() for a in alarms])) if alarms else math.nan,
            "periods": float(n)}
    res = CampaignResult(scores, healthy_alarm, _summary(scores, healthy_alarm), cal,
                         time.perf_counter() - t0, n_runs, n_healthy, machine_description())
    ex = next((s for s in scores if math.isfinite(s.t_failure_s)), None)
    if ex is not None:
        rec = results[ex.index]["record"]
        fr = FusedPredictor(cal, seed=seed + ex.index).run(rec.t_s, rec.table)
        res.example = {"index": ex.index, "t_s": rec.t_s.tolist(),
                       "b_true_um": (rec.truth["backlash_m"] * 1e6).tolist(),
                       "b_fused_um": fr.b_um.tolist(), "ci": rec.table["ci"].tolist(),
                       "ci_harmonic": rec.table["ci_harmonic"].tolist(),
                       "t_failure_s": ex.t_failure_s, "t_warning_s": fr.t_warning_s,
                       "pred_t": [p.t_pred_s for p in fr.predictions],
                       "pred_rul": [p.rul_s for p in fr.predictions],
                       "pred_lo": [p.band()[0] - p.t_pred_s for p in fr.predictions],
                       "pred_hi": [p.band()[1] - p.t_pred_s for p in fr.predictions]}
    return res


def _summary(scores: list[RunScore], healthy: dict[str, dict[str, float]]
             ) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for mth in METHODS:
        rs = [s.per_method[mth] for s in scores if not s.per_method[mth].get("censored")]
        if not rs:
            continue

        def med(key: str, rs: list[dict[str, Any]] = rs) -> float:
            v = np.array([r[key] for r in rs], dtype=float)
            return float(np.nanmedian(v)) if np.isfinite(v).any() else math.nan

        def frac(key: str, rs: list[dict[str, Any]] = rs) -> float:
            return float(np.mean([bool(r.get(key)) for r in rs]))

        out[mth] = {
            "runs": float(len(rs)),
            "warned_runs": float(np.mean([math.isfinite(r["t_warning_s"]) for r in rs])),
            "warning_life_frac_median": med("warning_life_frac"),
            "ph_life_frac_median": med("ph_life_frac"),
            "stable_ph_life_frac_median": med("stable_ph_life_frac"),
            "ph_before_half_life": float(np.mean([r["ph_life_frac"] >= 0.5 for r in rs])),
            "alpha_lambda_0.5": frac("alpha_lambda_0.5"),
            "alpha_lambda_0.7": frac("alpha_lambda_0.7"),
            "alpha_lambda_0.9": frac("alpha_lambda_0.9"),
            "ra_0.5_median": med("ra_0.5"), "ra_0.7_median": med("ra_0.7"),
            "ra_0.9_median": med("ra_0.9"),
            "false_alarm_period_rate": healthy[mth]["period_rate"],
            "false_alarm_run_rate": healthy[mth]["run_rate"],
        }
    return out


# --- figures and text ----------------------------------------------------------------------------

def figures(res: RulResult, out_dir: str | Path, suffix: str | None = None) -> list[Path]:
    """Figures like thesis figs. 6.11-6.15 (file names end in `suffix`, by default
    "_noise" for a run with sensor noise)."""
    if suffix is None:
        suffix = "_noise" if res.noisy else ""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rec, tr = res.record, res.truth_record
    t = rec.t_s
    paths = []
    fig, ax = plt.subplots(1, 2, figsize=(11, 3.6))
    ax[0].plot(t, rec.truth["preload_n"] / 1e3, label="preload (kN)")
    ax[0].plot(t, rec.truth["backlash_m"] * 1e5, label="backlash (x10 um)")
    ax[0].plot(t, rec.truth["friction_scale"], label="friction scale (-)")
    ax[0].set(title="RUL schedule (figs. 6.11-6.12)", xlabel="t (s)")
    ax[0].legend(fontsize=8)
    ax[1].plot(t, rec.table["ci"], ".", ms=3, label="Ci" + (" (noise)" if res.noisy else ""))
    if res.noisy:
        ax[1].plot(t, rec.table["ci_harmonic"], ".", ms=3, label="Ci, 15 harmonics (noise)")
        ax[1].plot(tr.t_s, tr.table["ci"], "k-", lw=1, label="Ci noise-free twin")
    for lv, nm, c in ((THRESHOLD, "threshold", "C2"), (WARNING, "warning", "C1"),
                      (FAILURE, "failure", "C3")):
        ax[1].axhline(lv, color=c, ls="--", lw=1, label=f"{nm} {lv}")
    ax[1].set(title="R1: Ci per command period (fig. 6.13)", xlabel="t (s)", ylabel="Ci (-)")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    p = out / f"r1_ci_trend{suffix}.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    paths.append(p)

    fig, ax = plt.subplots(1, 2, figsize=(11, 3.8))
    th = res.thesis
    if th is not None and th.prediction is not None:
        m = (t >= th.t_threshold_s - 5) & (t <= th.t_warning_s + 15)
        ax[0].plot(t[m], rec.table["ci"][m], "k.", ms=4, label="Ci")
        tt = np.linspace(th.t_threshold_s, th.point_toe_s if math.isfinite(th.point_toe_s)
                         else th.t_warning_s + 15, 300)
        ax[0].plot(tt, np.polyval(th.coeffs, (tt - th.t_warning_s) / th.scale_s), "C0-",
                   label="cubic fit, threshold -> warning")
        lo, hi = th.prediction.band()
        ax[0].axvspan(lo, min(hi, t[-1] + 20), color="C0", alpha=0.15,
                      label="bootstrap 90 % band of t(0.56)")
        ax[0].axvline(res.t_failure_s, color="C3", label="true failure")
        for lv, c in ((THRESHOLD, "C2"), (WARNING, "C1"), (FAILURE, "C3")):
            ax[0].axhline(lv, color=c, ls="--", lw=1)
        ax[0].set(title="R2: thesis cubic fit (fig. 6.14)", xlabel="t (s)", ylabel="Ci")
        ax[0].legend(fontsize=7)
    tt = t[t <= res.t_failure_s]
    ax[1].plot(tt, res.t_failure_s - tt, "k-", label="true RUL")
    ax[1].fill_between(tt, 0.8 * (res.t_failure_s - tt), 1.2 * (res.t_failure_s - tt),
                       color="k", alpha=0.08, label="+-20 % (alpha = 0.2)")
    if th is not None and th.prediction is not None:
        prof = thesis_profile(rec.t_s, rec.table["ci"], n_boot=100)
        if prof:
            ax[1].plot([p.t_pred_s for p in prof], [p.rul_s for p in prof], "C0.-", ms=3,
                       label="thesis cubic, re-fitted each period")
    if res.fused is not None and res.fused.predictions:
        ps = res.fused.predictions
        tp = np.array([p.t_pred_s for p in ps])
        ax[1].plot(tp, [p.rul_s for p in ps], "C1.-", ms=3, label="fused, median")
        ax[1].fill_between(tp, [p.band()[0] - p.t_pred_s for p in ps],
                           [min(p.band()[1] - p.t_pred_s, 200) for p in ps], color="C1",
                           alpha=0.25, label="fused, 90 % band")
    ax[1].set(title="R2: predicted vs true RUL (fig. 6.15)", xlabel="t (s)",
              ylabel="RUL (s)", ylim=(0, max(30.0, 0.6 * res.t_failure_s)))
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    p = out / f"r2_rul{suffix}.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    paths.append(p)
    return paths


def campaign_figure(res: CampaignResult, out_dir: str | Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(1, 3, figsize=(15, 3.8))
    for k, mth in enumerate(METHODS):
        ph = [s.per_method[mth].get("ph_life_frac", 0) for s in res.scores
              if not s.per_method[mth].get("censored")]
        wl = [s.per_method[mth].get("warning_life_frac", math.nan) for s in res.scores
              if not s.per_method[mth].get("censored")]
        x = np.arange(len(ph)) + (k - 1) * 0.27
        ax[0].bar(x, ph, width=0.27, label=mth)
        ax[1].plot(np.arange(len(wl)), wl, "o", label=mth)
    ax[0].axhline(0.5, color="k", ls="--", lw=1)
    ax[0].set(title="prognostic horizon / life (alpha 0.2)", xlabel="run", ylabel="PH / life")
    ax[1].set(title="warning time / life", xlabel="run", ylabel="fraction of life")
    for a in ax[:2]:
        a.legend(fontsize=7)
    ex = res.example
    if ex:
        t = np.asarray(ex["t_s"])
        ax[2].plot(t, ex["b_true_um"], "k-", label="true backlash")
        ax[2].plot(t, ex["b_fused_um"], "C1.", ms=2, label="fused estimate")
        ax[2].axhline(res.cal.fail_um, color="C3", ls="--", lw=1, label="b_fail")
        ax[2].axvline(ex["t_failure_s"], color="C3", lw=1)
        ax[2].set_yscale("symlog", linthresh=1.0)
        ax[2].set(title=f"run {ex['index']}: fused backlash estimate", xlabel="t (s)",
                  ylabel="backlash (um)")
        ax[2].legend(fontsize=7)
    fig.tight_layout()
    p = out / "campaign.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    return [p]


def campaign_markdown(res: CampaignResult) -> str:
    lines = [f"Generated by `bench hums campaign --runs {res.n_runs} --healthy "
             f"{res.n_healthy}` on {res.machine}; wall time {res.elapsed_s:.0f} s. "
             "Metrics from `progpy.metrics` (prognostic horizon, alpha-lambda with alpha = "
             "0.2, beta = 0.5) on each run's ToE samples; relative accuracy "
             "RA = 1 - |RUL_true - RUL_pred| / RUL_true of the median prediction; false "
             "alarms = share of healthy-run periods (and runs) with the warning on.", "",
             "| metric | thesis (Ci) | thesis (Ci, 15 harmonics) | fused |",
             "|---|---|---|---|"]
    keys = [("runs", "run-to-failure runs scored", "{:.0f}"),
            ("warned_runs", "runs with a warning before failure", "{:.0%}"),
            ("warning_life_frac_median", "warning time / life, median", "{:.0%}"),
            ("ph_life_frac_median", "prognostic horizon / life, median (progpy)", "{:.0%}"),
            ("stable_ph_life_frac_median", "horizon from which every prediction stays "
             "within alpha / life, median", "{:.0%}"),
            ("ph_before_half_life", "runs with a correct RUL band before 50 % of life",
             "{:.0%}"),
            ("alpha_lambda_0.5", "alpha-lambda met at 50 % of life", "{:.0%}"),
            ("alpha_lambda_0.7", "alpha-lambda met at 70 % of life", "{:.0%}"),
            ("alpha_lambda_0.9", "alpha-lambda met at 90 % of life", "{:.0%}"),
            ("ra_0.5_median", "relative accuracy at 50 %, median", "{:.2f}"),
            ("ra_0.7_median", "relative accuracy at 70 %, median", "{:.2f}"),
            ("ra_0.9_median", "relative accuracy at 90 %, median", "{:.2f}"),
            ("false_alarm_period_rate", "false alarms, share of healthy periods", "{:.2%}"),
            ("false_alarm_run_rate", "false alarms, share of healthy runs", "{:.0%}")]
    for k, label, f in keys:
        cells = []
        for mth in METHODS:
            v = res.summary.get(mth, {}).get(k, math.nan)
            cells.append("-" if not math.isfinite(v) else f.format(v))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    cal = res.cal
    lines += ["", "Fusion weights (share): " + ", ".join(
        f"{f} {w / sum(cal.weights.values()):.1%}" for f, w in cal.weights.items())
        + "; noise of each estimate on healthy runs (um): "
        + ", ".join(f"{f} {s:.2f}" for f, s in cal.sigma_um.items())
        + f"; warning at {cal.warn_um:.2f} um, fit floor {cal.floor_um:.2f} um, "
        f"b_fail {cal.fail_um:.1f} um.", "",
        "Randomised per run (uniform): " + ", ".join(
            f"`{k}` {a:g}-{b:g}" for k, (a, b) in CAMPAIGN_RANGES.items())
        + "; sensor noise on with a new seed per run. Healthy runs: no backlash, friction "
          "x0.9-1.1, preload 0 or 1-3 kN held, 120 s, noise on."]
    return "\n".join(lines) + "\n"


def campaign_json(res: CampaignResult) -> dict[str, Any]:
    def enc(v: Any) -> Any:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {k: enc(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [enc(x) for x in v]
        if isinstance(v, (np.floating, np.integer)):
            return enc(v.item())
        if isinstance(v, np.bool_):
            return bool(v)
        return v
    return enc({"summary": res.summary, "healthy_alarm": res.healthy_alarm,
                "runs": [{"index": s.index, "params": s.params, "t_failure_s": s.t_failure_s,
                          "methods": s.per_method} for s in res.scores],
                "calibration": {k: v for k, v in res.cal.to_json().items()
                                if k != "healthy_fused_um"},
                "elapsed_s": res.elapsed_s, "machine": res.machine})


def markdown(res: RulResult, figure_paths: list[Path] | None = None,
             doc_dir: Path | None = None) -> str:
    from bench.hums.table import figure_links
    from bench.hums.table import markdown as table
    text = [f"Generated by `bench hums rul{' --noise' if res.noisy else ''}` on "
            f"{res.machine}; wall time {res.elapsed_s:.1f} s (120 s run at 10 kHz switching "
            "PWM with dynamic balls" + (", its noise-free twin" if res.noisy else "")
            + (", and the fusion calibration" if res.fused is not None else "") + "). "
            f"Monitor gain {res.gain / M.THESIS_SET_GAIN_V_PER_M:.1f} (thesis units).", "",
            table(rows(res))]
    if figure_paths:
        text += [""] + figure_links(figure_paths, doc_dir)
    return "\n".join(text) + "\n"
