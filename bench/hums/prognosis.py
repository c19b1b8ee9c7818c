"""Prognosis from usage and health together (beyond the thesis): a wear state
driven by usage, updated by the health indexes of ground tests, and an RUL distribution.

The HUMS's wear model (`WearModel`, a progpy `PrognosticsModel`):

- state ``w``: normalised wear, 0 new, 1 at failure (the worn volume over the volume at
  which the noise-free Ci of the ground test, eq. 6.6, reaches the thesis' failure level
  0.56, section 6.5); ``lnk``: the log of this actuator's wear coefficient, which the HUMS
  does not know (Archard: worn volume = k x contact load x rolling distance / H, so
  w grows as k times the usage's Archard exposure); ``lfs``: the log of this actuator's
  friction scale when new (its friction current differs from the nominal by a few %);
- input ``e``: the usage's exposure rate (per time unit): the first moment of the load
  spectrum, sum |F| n over screw revolutions (N rev, `exposure_of_usage`), or 1 when the
  prognosis runs on time alone (trends from another rig);
- dynamics: w' = w + exp(lnk) e dt (Archard, linear in the exposure); lnk, lfs constant
  (a small random walk keeps the particle set diverse);
- outputs: the health indexes of a ground test, each a calibrated curve of w
  (`PrognosisCalibration.curves`, from noise-free ground tests at known worn volumes),
  Gaussian noise measured on repeated noisy ground tests; the friction current times
  exp(lfs);
- event ``failure``: w >= 1.

Estimation: progpy's `ParticleFilter` on the vectorised model (`WearPrognoser.update`).
Prediction: the time of failure of each particle, t + (1 - w) / (exp(lnk) e_future), with
e_future the actuator's mean exposure rate so far (the usage's rate of consumption); this
is what progpy's `MonteCarlo` predictor computes by stepping the same model (a unit test
checks the two agree), in closed form: MonteCarlo steps every sample through Python per
time step, ~1,000x slower, too slow for a 50-actuator campaign predicting every day.

Before any ground test the particles are the prior: w = 0 (new) and lnk from the
calibration actuators (`PrognosisCalibration.lnk_mean/lnk_std`), so usage alone gives an
RUL distribution from day one; the health indexes then move it as wear shows.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums.rul import Prediction

FRICTION_INDEX = "friction_current_a"
INDEXES = ("friction_current_a", "lost_motion_um", "ci_harmonic")
"""Health indexes the campaign's calibration has curves for (per ground test; names as in
`bench.hums.periods.as_table`, lost motion in um); plain Ci is left out: sensor noise
biases it (0.89 on a healthy actuator, H6) and Ci on 15 harmonics carries the same
information. A calibration file may hold curves of other indexes."""
PERCENTILES = (5.0, 25.0, 50.0, 75.0, 95.0)
T0 = -1e-6
"""Start time of the filter: a first ground test at t = 0 is an update."""


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


@dataclass
class PrognosisCalibration:
    """The observation model (index curves of w and their noise), the prior of the wear
    coefficient, and the warning level, with the seeds they came from."""
    w_grid: list[float]
    curves: dict[str, list[float]]     # noise-free value of each index at each w
    sigma: dict[str, float]            # noise of each index (one ground test)
    lnk_mean: float                    # prior of ln k, k in w per unit of exposure
    lnk_std: float
    lnk_time_mean: float               # prior of ln k when the exposure is time (w/day)
    lnk_time_std: float
    exposure_rate_mean: float          # population mean exposure per day (first day)
    lfs_std: float = 0.05              # prior std of the log friction scale
    warn_w: float = math.nan           # warning: index-only w estimate above this
    v_fail_m3: float = math.nan        # worn volume of w = 1 on the calibration actuator
    seeds: dict[str, list[int]] = field(default_factory=dict)
    notes: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> PrognosisCalibration:
        try:
            cal = cls(**d)
        except TypeError as exc:
            raise BenchError(f"not a prognosis calibration: {exc}") from None
        cal._check()
        return cal

    def _check(self) -> None:
        """BenchError naming the first field of a read calibration that has the wrong
        shape (the filter would fail on it later with a TypeError)."""
        def numbers(x: Any, n: int | None = None) -> bool:
            return (isinstance(x, list) and all(_is_number(v) for v in x)
                    and (n is None or len(x) == n))
        n = len(self.w_grid) if numbers(self.w_grid) else 0
        checks = [("w_grid", n >= 2, "a list of at least 2 numbers"),
                  ("curves", isinstance(self.curves, dict)
                   and all(numbers(c, n) for c in self.curves.values()),
                   "index name -> a list of numbers, one per w_grid point"),
                  ("sigma", isinstance(self.sigma, dict)
                   and all(_is_number(v) for v in self.sigma.values()),
                   "index name -> a number")]
        checks += [(k, _is_number(getattr(self, k)), "a number") for k in (
            "lnk_mean", "lnk_std", "lnk_time_mean", "lnk_time_std", "exposure_rate_mean",
            "lfs_std", "warn_w", "v_fail_m3")]
        for name, ok, what in checks:
            if not ok:
                raise BenchError(f"not a prognosis calibration: {name} is not {what}")

    def curve(self, name: str, w: np.ndarray) -> np.ndarray:
        """The index `name` at wear w (linear beyond both ends of the grid)."""
        g = np.asarray(self.w_grid, dtype=float)
        c = np.asarray(self.curves[name], dtype=float)
        w = np.asarray(w, dtype=float)
        out = np.interp(w, g, c)
        hi, lo = w > g[-1], w < g[0]
        out = np.where(hi, c[-1] + (w - g[-1]) * (c[-1] - c[-2]) / (g[-1] - g[-2]), out)
        return np.where(lo, c[0] + (w - g[0]) * (c[1] - c[0]) / (g[1] - g[0]), out)

    def index_w(self, name: str, value: float) -> float:
        """Invert the curve of `name` (made monotone): the w an index value says, held
        at the ends of the grid (no extrapolation)."""
        g = np.asarray(self.w_grid, dtype=float)
        c = np.asarray(self.curves[name], dtype=float)
        sign = 1.0 if c[-1] >= c[0] else -1.0
        cm = np.maximum.accumulate(sign * c)
        return float(np.interp(sign * value, cm, g))

    def slope(self, name: str) -> float:
        """Mean slope of the index over the grid (value per unit w)."""
        c = self.curves[name]
        return (c[-1] - c[0]) / (self.w_grid[-1] - self.w_grid[0])


def exposure_of_usage(load_spectrum_rev: np.ndarray, edges_n: np.ndarray) -> float:
    """Archard exposure of a run's usage: sum |F| n over the load spectrum (N rev), the bin
    centres (the open end bins at their finite edge)."""
    e = np.asarray(edges_n, dtype=float)
    lo, hi = e[:-1].copy(), e[1:].copy()
    lo[~np.isfinite(lo)] = hi[~np.isfinite(lo)]
    hi[~np.isfinite(hi)] = lo[~np.isfinite(hi)]
    return float(np.sum(np.asarray(load_spectrum_rev) * np.abs(0.5 * (lo + hi))))


def index_wear(cal: PrognosisCalibration, obs: dict[str, float]) -> float:
    """Wear w from one ground test's indexes alone (inverse-variance weighted inversion of
    each curve): the warning's statistic, no usage and no history."""
    num = den = 0.0
    for name, v in obs.items():
        if name not in cal.curves or not math.isfinite(v):
            continue
        s = abs(cal.slope(name))
        if s <= 0:
            continue
        wi = cal.index_w(name, v)
        if not math.isfinite(wi):
            continue
        var = (cal.sigma[name] / s) ** 2
        num += wi / var
        den += 1.0 / var
    return num / den if den > 0 else math.nan


def make_model(cal: PrognosisCalibration, outputs: list[str], process_w: float = 2e-3,
               process_lnk: float = 0.03) -> Any:
    """The progpy wear model (module docstring) with the given output indexes."""
    import matplotlib
    with matplotlib.rc_context():   # importing progpy rewrites matplotlib's rcParams
        from progpy import PrognosticsModel

    class WearModel(PrognosticsModel):  # type: ignore[misc]
        """Normalised wear w driven by the Archard exposure, indexes as outputs."""
        is_vectorized = True
        states = ["w", "lnk", "lfs"]
        inputs = ["e"]
        events = ["failure"]
        default_parameters = {"x0": {"w": 0.0, "lnk": 0.0, "lfs": 0.0}}

        def __init__(self, **kw: Any) -> None:
            self.outputs = list(outputs)
            super().__init__(**kw)
            # progpy binds `no_process_noise` when the process_noise parameter is 0; the
            # random walk below is this model's own
            self.apply_process_noise = self._random_walk

        def initialize(self, u: Any = None, z: Any = None) -> Any:
            return self.StateContainer(self.parameters["x0"])

        def next_state(self, x: Any, u: Any, dt: float) -> Any:
            return self.StateContainer({"w": x["w"] + np.exp(x["lnk"]) * u["e"] * dt,
                                        "lnk": x["lnk"], "lfs": x["lfs"]})

        def _random_walk(self, x: Any, dt: float = 1) -> Any:
            n = np.shape(x["w"])
            rng = self.parameters["rng"]
            return self.StateContainer({
                "w": x["w"] + rng.normal(0.0, process_w * math.sqrt(dt), n),
                "lnk": x["lnk"] + rng.normal(0.0, process_lnk * math.sqrt(dt), n),
                "lfs": x["lfs"] + rng.normal(0.0, 0.002, n)})

        def output(self, x: Any) -> Any:
            out = {}
            for name in self.outputs:
                v = cal.curve(name, x["w"])
                if name == FRICTION_INDEX:
                    v = v * np.exp(x["lfs"])
                out[name] = v
            return self.OutputContainer(out)

        def event_state(self, x: Any) -> dict[str, Any]:
            return {"failure": np.maximum(1.0 - x["w"], 0.0)}

        def threshold_met(self, x: Any) -> dict[str, Any]:
            return {"failure": x["w"] >= 1.0}

    return WearModel()


@dataclass
class RulEstimate:
    """An RUL distribution made at `t`: percentiles of the RUL, of w, the warning."""
    t: float
    rul_pct: dict[str, float]
    w_pct: dict[str, float]
    lnk_median: float
    index_w: float
    warning: bool
    observed: bool            # a ground test was used at this time (else usage only)

    def row(self) -> dict[str, float]:
        out: dict[str, float] = {"t": self.t}
        out.update({f"rul_p{k}": v for k, v in self.rul_pct.items()})
        out.update({f"w_p{k}": v for k, v in self.w_pct.items()})
        out.update(lnk_median=self.lnk_median, index_w=self.index_w,
                   warning=float(self.warning), observed=float(self.observed))
        return out


class WearPrognoser:
    """Particle filter on the wear model of one actuator (progpy `ParticleFilter`).

    `update(t, exposure, obs)` moves the particles by the exposure accumulated since the
    last update (the usage) and weighs them by the ground test's indexes `obs` (names
    in `cal.curves`; missing or NaN ones carry no weight); `predict()` gives failure-time
    samples; `estimate()` the percentiles. `time_only=True` uses time as the exposure
    (the prior of k in w per time unit): trends without usage."""

    def __init__(self, cal: PrognosisCalibration, outputs: list[str] | None = None,
                 n_particles: int = 1000, seed: int = 0, time_only: bool = False) -> None:
        import matplotlib
        with matplotlib.rc_context():
            from progpy.state_estimators import ParticleFilter
            from progpy.uncertain_data import UnweightedSamples
        self.cal = cal
        self.outputs = [o for o in (outputs or list(cal.curves)) if o in cal.curves]
        if not self.outputs:
            raise BenchError("none of the health indexes has a calibration curve "
                             f"(known: {', '.join(cal.curves)})")
        self.time_only = time_only
        self.rng = np.random.default_rng(seed)
        self.model = make_model(cal, self.outputs)
        self.model.parameters["rng"] = self.rng
        mu, sd = ((cal.lnk_time_mean, cal.lnk_time_std) if time_only
                  else (cal.lnk_mean, cal.lnk_std))
        n = int(n_particles)
        x0 = {"w": np.abs(self.rng.normal(0.0, 0.01, n)),
              "lnk": self.rng.normal(mu, sd, n),
              "lfs": self.rng.normal(0.0, cal.lfs_std, n)}
        self.noise = {o: float(cal.sigma[o]) for o in self.outputs}
        # the drawn particles as they are (with `num_particles` progpy would resample
        # them from numpy's global random state)
        self.pf = ParticleFilter(self.model, UnweightedSamples(
            [dict(zip(x0, v, strict=True)) for v in zip(*x0.values(), strict=True)]),
            measurement_noise=dict(self.noise), t0=T0,
            resample_fcn=self._resample)
        self.t = T0
        self.exposure_total = 0.0
        self.history: list[RulEstimate] = []

    def _resample(self, weights: np.ndarray) -> np.ndarray:
        """Residual resampling (Liu and Chen 1998, progpy's default) drawing from this
        prognoser's seeded generator: filterpy's version draws from numpy's global
        random state, which would make the filter differ from run to run."""
        w = np.asarray(weights, dtype=float)
        n = len(w)
        counts = np.floor(n * w).astype(int)
        idx = np.repeat(np.arange(n), counts)
        rest = n - len(idx)
        if rest > 0:
            resid = n * w - counts
            cs = np.cumsum(resid / resid.sum())
            cs[-1] = 1.0
            idx = np.concatenate([idx, np.searchsorted(cs, self.rng.random(rest))])
        return idx

    def particles(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v, dtype=float) for k, v in self.pf.particles.items()}

    def update(self, t: float, exposure: float = math.nan,
               obs: dict[str, float] | None = None) -> RulEstimate:
        """Advance to `t` with `exposure` used since the last update (ignored when
        time-only), weigh by the indexes `obs`; returns the estimate at `t`."""
        dt = float(t) - self.t
        if dt < 0:
            raise BenchError(f"times must increase: {t} after {self.t}")
        if not self.time_only:
            if not math.isfinite(exposure) or exposure < 0:
                raise BenchError(f"exposure must be a number >= 0, got {exposure}")
            self.exposure_total += exposure
        good = {k: float(v) for k, v in (obs or {}).items()
                if k in self.outputs and v is not None and math.isfinite(float(v))}
        rate = 1.0 if self.time_only else (exposure / dt if dt > 0 else 0.0)
        if good and dt > 0:
            z = {o: good.get(o, 0.0) for o in self.outputs}
            # an index this ground test lacks carries no weight (a very wide likelihood)
            self.pf.parameters["measurement_noise"] = {
                o: (self.noise[o] if o in good else 1e12) for o in self.outputs}
            self.pf.estimate(float(t), {"e": rate}, z, dt=dt)
        elif dt > 0:                       # usage only: move the particles, no weighing
            p = self.pf.particles
            x = self.model.apply_process_noise(self.model.next_state(p, {"e": rate}, dt), dt)
            self.pf.particles = x
            self.pf.t = float(t)
        elif good:
            raise BenchError(f"two ground tests at the same time {t}")
        self.t = float(t)
        est = self.estimate(good)
        self.history.append(est)
        return est

    def future_rate(self) -> float:
        """Exposure per time unit expected from now on: the mean rate so far (the usage's
        rate of consumption), the population's before any flight."""
        if self.time_only:
            return 1.0
        if self.t > 0 and self.exposure_total > 0:
            return self.exposure_total / self.t
        return self.cal.exposure_rate_mean

    def toe_samples(self) -> np.ndarray:
        """Time of failure of each particle under the future exposure rate."""
        p = self.particles()
        rate = np.exp(p["lnk"]) * self.future_rate()
        with np.errstate(divide="ignore"):
            return self.t + np.where(rate > 0, np.maximum(1.0 - p["w"], 0.0) / rate, np.inf)

    def prediction(self) -> Prediction:
        return Prediction(self.t, self.toe_samples())

    def estimate(self, obs: dict[str, float] | None = None) -> RulEstimate:
        p = self.particles()
        rul = self.toe_samples() - self.t
        wi = index_wear(self.cal, obs or {})
        return RulEstimate(
            self.t, {f"{q:g}": float(np.percentile(rul, q)) for q in PERCENTILES},
            {f"{q:g}": float(np.percentile(p["w"], q)) for q in PERCENTILES},
            float(np.median(p["lnk"])), wi,
            bool(math.isfinite(wi) and wi > self.cal.warn_w), bool(obs))
