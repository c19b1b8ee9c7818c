"""The fused predictor's calibration (`bench.hums.fusion.Calibration`), built from runs.

- Feature -> backlash maps and b_fail: the noise-free H4 sine (2 s) at the 11 points of
  the degradation sweep (backlash 0-100 um, friction x1-x4, `bench.hums.sweep.degraded`,
  thesis section 6.4), plus three zero-backlash friction points that separate backlash
  from the contacts' elastic give in the lost motion. b_fail is the backlash at which the
  sweep's Ci (eq. 6.6) crosses the thesis' failure level 0.56.
- Noise of each estimate, fusion weights, warning level and fit floor: noisy healthy runs
  (no backlash, friction +-10 %, a held preload of 0-3 kN).

The runs go to the worker pool (`bench.runtime.workers.run_all`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench import BenchError
from bench.hums import monitor as M
from bench.hums.fusion import (
    FEATURES,
    Calibration,
    causal_median,
    crossing_backlash,
    estimates,
    feature_values,
    fused_backlash,
    fused_sigma,
)
from bench.hums.records import RunRecord, record_from_trace, simulate_record
from bench.hums.rul import FAILURE
from bench.hums.sweep import degraded
from bench.profiles.catalog import make_profile
from bench.runtime.workers import run_all
from bench.sim.harness import simulate
from plant_rt.params import PlantParams
from plant_rt.paramvalues import seed_in_range

CALIBRATION_VERSION = 3     # part of the report's cache key: bump when calibrate() changes


def _calib_point(job: tuple[float, float, str, float | None]) -> dict[str, Any]:
    """Worker: noise-free H4 sine (2 s) at degradation d (or, with `friction`, at zero
    backlash and that friction scale), per-period features of periods 2-4 averaged (the
    first period holds the start-up transient)."""
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


def healthy_params(base: PlantParams, rng: np.random.Generator, seed: int) -> PlantParams:
    """A healthy actuator: no backlash, friction within +-10 % of nominal (spread between
    units), a preload of 0-3 kN held constant, sensor noise on."""
    return base.with_dict({"schedule.kind": "none", "effects.backlash_m": 0.0,
                           "effects.friction_scale": float(rng.uniform(0.9, 1.1)),
                           "effects.preload_n": float(rng.choice([0.0, rng.uniform(1e3, 3e3)])),
                           "sensors.noise": True, "sensors.noise_seed": seed_in_range(seed)})


def _healthy_record(job: tuple[str, float, float]) -> RunRecord:
    """Worker: one noisy healthy run, indexed per period."""
    pj, kp, dur = job
    return simulate_record(PlantParams.from_json(pj), kp, dur)


def calibrate(base: PlantParams | None = None, kp: float | None = None,
              n_healthy: int = 4, healthy_s: float = 60.0, seed: int = 12345,
              workers: int | None = None, progress: bool = True,
              scheduler: str | None = None) -> Calibration:
    """Build the fusion's calibration: the noise-free H4 sweep (11 points) gives each
    feature's map to backlash and b_fail (where its Ci crosses 0.56); `n_healthy` noisy
    healthy runs give each estimate's noise, the weights and the warning level."""
    base = base or PlantParams()
    if kp is None:
        kp = M.fitted(base)[0].gain_rad_s_per_m
    pj = base.to_json()
    rng = np.random.default_rng(seed)
    hjobs = [(healthy_params(base, rng, seed + k).to_json(), kp, healthy_s)
             for k in range(n_healthy)]
    levels = np.linspace(0.0, 1.0, 11)
    res = run_all(_job, [("h", j) for j in hjobs]
                  + [("c", (float(d), kp, pj, None)) for d in levels]
                  + [("c", (0.0, kp, pj, fr)) for fr in (2.0, 3.0, 4.0)], workers, progress,
                  desc="hums calibration", unit="run", scheduler=scheduler)
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
    hf = np.concatenate([causal_median(fused_backlash(r.table, cal), 3)[1:]
                         for r in healthy]) if healthy else np.array([0.0])
    s_f = fused_sigma(cal)
    # warning: above every healthy 3-period median seen, with margin, and >= 6 sigma
    cal.warn_um = float(max(1.5 * np.max(hf), 6.0 * s_f, 0.5))
    cal.floor_um = float(max(5.0 * s_f, 0.5))
    cal.healthy_fused_um = hf.tolist()
    return cal


def _job(job: tuple[str, Any]) -> Any:
    """Worker: a calibration point ("c") or a healthy run ("h")."""
    kind, arg = job
    if kind == "c":
        return _calib_point(arg)
    if kind == "h":
        return _healthy_record(arg)
    raise BenchError(f"unknown job {kind!r}")


def _fail_backlash(b_um: list[float], ci: list[float], failure: float = FAILURE) -> float:
    """The backlash at which the sweep's Ci crosses `failure` (linear interpolation)."""
    return crossing_backlash(b_um, ci, failure)
