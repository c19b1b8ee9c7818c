"""Calibration of another actuator from its healthy logs (`bench calibrate --actuator`).

What the description (`bench.rig.actuator`) leaves unknown is identified from one or more
healthy logs with the generic model (`bench.sim.rigmodel`), by least squares on the
residuals at the logs' own sample instants, each signal's residual divided by that log's
noise floor (`bench.signals.estimators.noise_floor`, from the measured samples):

- ``fit-gains`` (a set-point is logged): the closed loop with a generic position/speed
  cascade; the unknown gains, feed-forward and current limit are fitted together with
  the unknown physical values (mass, force per ampere, friction, current offset),
  against position and, where logged, current;
- ``measured-current`` (a drive with a current loop, current logged): no controller;
  the measured current drives the mechanics, the unknown physical values are fitted
  against position;
- ``described`` (every gain known): the closed loop with the described controller.

Then every held-out log is re-simulated with the calibrated values and its RMS residual
per signal is set against its own noise floor. When a held-out signal stays above
`FLOOR_FACTOR` x its floor the output says so and points at the healthy baseline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from bench import BenchError
from bench.gap.inputs import Calibration
from bench.rig.actuator import Actuator, model_values
from bench.signals.estimators import noise_floor
from bench.signals.trace import Trace
from bench.sim import rigmodel as RM

METHODS = ("auto", "fit-gains", "measured-current")
FLOOR_FACTOR = 2.0
"""A model reproduces a log when its RMS residual is within this factor of the floor."""
NEEDS = {
    "fit-gains": ("setpoint_position_m", "position_m"),
    "measured-current": ("current_a", "position_m"),
}
"""Signals each calibration method needs (current_a is also used by fit-gains if logged)."""
MIN_FLOOR = {"position_m": 1e-7, "current_a": 1e-4}
MIN_SAMPLES = 5
"""Measured samples a signal's noise floor needs (`bench.signals.estimators.noise_floor`): a log with
fewer position samples cannot be scored against the model."""
DEFAULT_PERIOD_S = 1e-3
X0_FLOORS = 20.0     # the initial nut position is fitted within +- this many floors
GAINS = ("kp_1_s", "kv_a_s_per_m", "ki_a_per_m", "feedforward", "current_limit_a")
PHYSICAL = ("mass_kg", "force_per_a_n", "coulomb_n", "viscous_n_s_per_m", "current_offset_a")
LINEAR = ("current_offset_a", "feedforward")     # fitted on a linear scale, others log


def _has(tr: Trace, name: str) -> bool:
    return name in tr and bool(np.isfinite(tr[name]).any())


def too_short(tr: Trace) -> str | None:
    """Why `tr` is too short to be scored against the model (None when it is not): its
    length and what it needs (`MIN_SAMPLES` position samples)."""
    n = int(np.isfinite(tr["position_m"]).sum()) if "position_m" in tr else 0
    if n >= MIN_SAMPLES:
        return None
    dt = tr.dt
    span = float(tr.t[-1] - tr.t[0]) if len(tr) else 0.0
    rate = f", {(MIN_SAMPLES - 1) * dt:.3g} s at its {dt * 1e3:.3g} ms rate" if dt > 0 else ""
    return (f"the log is too short: {n} position sample(s) over {span:.3g} s; the model's "
            f"noise floor needs at least {MIN_SAMPLES} samples{rate}")


def choose_method(traces: Sequence[Trace], act: Actuator, method: str) -> str:
    """The calibration method (module doc); BenchError saying what a log lacks."""
    if method not in METHODS:
        raise BenchError(f"method must be one of {', '.join(METHODS)}")
    if method == "auto":
        known = all(model_values(act)[g] is not None for g in GAINS[:3])
        if all(_has(t, "setpoint_position_m") for t in traces):
            method = "described" if known else "fit-gains"
        else:
            method = "measured-current"
    if method == "measured-current" and not act.has_current_loop:
        raise BenchError(f"a re-simulation driven by the measured current needs a drive "
                         f"with a current loop; {act.name} is a {act.motor_kind} (its "
                         "logged current is not its torque): log the set-point instead")
    for i, tr in enumerate(traces):
        miss = [s for s in NEEDS.get(method, NEEDS["fit-gains"]) if not _has(tr, s)]
        src = tr.meta.get("source", f"log {i + 1}")
        if miss:
            raise BenchError(f"{src}: calibration ({method}) not available: needs "
                             f"{', '.join(miss)}")
        short = too_short(tr)
        if short:
            raise BenchError(f"{src}: calibration ({method}) not available: {short}")
    return method


STARTS = ((10.0, 200.0), (2.0, 30.0), (30.0, 1000.0))
"""Start points of a cascade fit: (position gain 1/s, speed-loop bandwidth rad/s); the
fit from each runs and the lowest cost on the calibration logs is kept."""


def _start(traces: Sequence[Trace], act: Actuator, kp: float = 10.0, wv: float = 200.0
           ) -> dict[str, float]:
    """Start values of the unknowns, from the logs' scales (not fitted to them)."""
    cur = np.concatenate([np.asarray(t["current_a"], float) for t in traces
                          if _has(t, "current_a")] or [np.ones(1)])
    cur = cur[np.isfinite(cur)]
    imax = float(np.max(np.abs(cur))) or 1.0
    lead = act.values.get("lead_m") or 5e-3
    kf = 2.0 * math.pi / lead          # ~1 N m per A at the motor, direct drive
    mass = 3e-4 * (2.0 * math.pi / lead) ** 2   # a 3e-4 kg m^2 rotor, direct drive
    return {"mass_kg": mass, "force_per_a_n": kf, "coulomb_n": 0.1 * kf * imax,
            "viscous_n_s_per_m": 0.01 * kf * imax / 0.02,
            "current_offset_a": float(np.min(cur)) if cur.size else 0.0,
            "kp_1_s": kp, "kv_a_s_per_m": wv * mass / kf, "ki_a_per_m": 0.2 * wv * wv * mass / kf,
            "feedforward": 1.0, "current_limit_a": 2.0 * imax, "current_tau_s": 0.0}


class _Fit:
    """The unknowns <-> a vector in fit coordinates (log scale except LINEAR)."""

    def __init__(self, values: dict[str, float | None], free: Sequence[str],
                 start: dict[str, float]) -> None:
        self.free = list(free)
        self.fixed = {**RM.EXTRA, **{k: (v if v is not None else start[k])
                                     for k, v in values.items() if k in RM.THETA}}

    def theta(self, z: np.ndarray) -> np.ndarray:
        v = dict(self.fixed)
        for k, zi in zip(self.free, z, strict=True):
            v[k] = float(zi) if k in LINEAR else float(10.0 ** zi)
        return np.array([v[k] for k in RM.THETA])

    def z0(self) -> np.ndarray:
        return np.array([self.fixed[k] if k in LINEAR else math.log10(max(self.fixed[k], 1e-9))
                         for k in self.free])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        span = {"feedforward": None, "current_offset_a": 5.0}
        lo, hi = [], []
        for k, z in zip(self.free, self.z0(), strict=True):
            w = span.get(k, 4.0)
            lo.append(0.0 if w is None else z - w)
            hi.append(1.5 if w is None else z + w)
        return np.array(lo), np.array(hi)


class _Held:
    """A fixed theta with the `_Fit` interface (no free value)."""
    free: list[str] = []

    def __init__(self, theta: np.ndarray) -> None:
        self._theta = theta

    def theta(self, z: np.ndarray) -> np.ndarray:
        return self._theta


def simulate(theta: np.ndarray, tr: Trace, act: Actuator, method: str, period_s: float,
             dx0: float = 0.0) -> dict[str, np.ndarray]:
    """The model's signals at `tr`'s instants under `method`; the closed loop starts
    with the nut at the first position sample + `dx0`."""
    load = (tr["load_force_n"] * load_sign(act) if _has(tr, "load_force_n")
            else np.zeros(len(tr)))
    pos = np.asarray(tr["position_m"], float)
    if method == "measured-current":
        return {"position_m": RM.current_driven(theta, tr.t, tr["current_a"], pos, load)}
    x0 = float(pos[np.isfinite(pos)][0]) + dx0
    x, i = RM.closed_loop(theta, act.motor_kind == "stepper_chopper", tr.t,
                          np.nan_to_num(tr["setpoint_position_m"]), load, period_s, x0)
    out = {"position_m": x}
    if _has(tr, "current_a"):
        out["current_a"] = i
    return out


def load_sign(act: Actuator) -> float:
    """The description's load sign (+1 or -1, validated by `bench.rig.actuator`); +1 when it
    is unknown (`_notes` says so)."""
    sign = act.values.get("load_sign")
    return 1.0 if sign is None else float(sign)


def floors(tr: Trace) -> dict[str, float]:
    """Noise floor per compared signal, from `tr`'s own samples."""
    return {s: max(noise_floor(tr[s]), MIN_FLOOR[s]) for s in MIN_FLOOR if _has(tr, s)}


def _residual(z: np.ndarray, fit: _Fit | _Held, traces: Sequence[Trace], fl: Sequence[dict[str, float]],
              act: Actuator, method: str, period_s: float) -> np.ndarray:
    nz = len(fit.free)
    th = fit.theta(z[:nz])
    parts = []
    for k, (tr, f) in enumerate(zip(traces, fl, strict=True)):
        dx0 = float(z[nz + k]) * f["position_m"] if len(z) > nz else 0.0
        sim = simulate(th, tr, act, method, period_s, dx0)
        for s, y in sim.items():
            r = (np.asarray(tr[s], float) - y) / f[s]
            parts.append(np.clip(np.nan_to_num(r, nan=1e3), -1e4, 1e4)[np.isfinite(tr[s])])
    return np.concatenate(parts) / math.sqrt(max(len(traces), 1))


def score(theta: np.ndarray, tr: Trace, act: Actuator, method: str, period_s: float
          ) -> dict[str, dict[str, float]]:
    """RMS residual per signal of `tr` against its noise floor (the closed loop's initial
    nut position fitted within the first sample's noise: an initial condition, not a
    model value)."""
    fl = floors(tr)
    sim = simulate(theta, tr, act, method, period_s, fit_x0(theta, tr, act, method, period_s))
    out = {}
    for s, y in sim.items():
        r = np.asarray(tr[s], float) - y
        ok = np.isfinite(r)
        rms = float(np.sqrt(np.mean(r[ok] ** 2))) if ok.any() else float("nan")
        out[s] = {"rms": rms, "noise_floor": fl[s], "ratio": rms / fl[s]}
    return out


def fit_x0(theta: np.ndarray, tr: Trace, act: Actuator, method: str, period_s: float
           ) -> float:
    """The closed loop's initial nut position offset (m) from the first sample that fits
    `tr` best, within X0_FLOORS position floors (0 for the measured-current drive)."""
    if method == "measured-current":
        return 0.0
    fl = floors(tr)
    sol = least_squares(_residual, np.zeros(1), bounds=(-X0_FLOORS, X0_FLOORS),
                        args=(_Held(theta), [tr], [fl], act, method, period_s), max_nfev=30)
    return float(sol.x[0]) * fl["position_m"]


def theta_of(cal: dict[str, Any]) -> np.ndarray:
    """The model vector of a calibration (`calibrate_rig`'s output)."""
    v = {**RM.EXTRA, **cal["values"]}
    return np.array([float(v[k]) for k in RM.THETA])


def _free(act: Actuator, method: str) -> tuple[list[str], dict[str, float | None]]:
    vals = model_values(act)
    names = list(PHYSICAL) + ([] if method != "fit-gains" else list(GAINS))
    if act.motor_kind == "stepper_chopper" or method == "measured-current":
        vals["current_tau_s"] = vals["current_tau_s"] or 0.0
    if method == "measured-current":
        for g in GAINS:
            vals[g] = vals[g] if vals[g] is not None else 0.0
    return [n for n in names if vals[n] is None], vals


def calibrate_rig(healthy: Sequence[Trace], act: Actuator,
                  holdout: Sequence[Trace] = (), method: str = "auto") -> dict[str, Any]:
    """Identify what `act` leaves unknown from `healthy`; score `holdout` (module doc)."""
    t0 = time.perf_counter()
    if not healthy:
        raise BenchError("calibration needs at least one healthy log")
    method = choose_method(list(healthy) + list(holdout), act, method)
    period_s = act.controller.get("sample_period_s") or DEFAULT_PERIOD_S
    free, vals = _free(act, method)
    notes = _notes(act, method, period_s, vals)
    theta, ci, starts = _fit_all(healthy, act, method, period_s, free, vals)
    values = {k: float(v) for k, v in zip(RM.THETA, theta, strict=True)}
    fit_scores = [score(theta, t, act, method, period_s) for t in healthy]
    held = [score(theta, t, act, method, period_s) for t in holdout]
    reach = _reaches(held or fit_scores)
    if not reach:
        notes.append(f"no model of this family reaches {FLOOR_FACTOR:g} x the noise floor on "
                     f"the {'held-out' if held else 'calibration'} logs: diagnose against a "
                     "baseline built from several healthy runs (the healthy-baseline "
                     "fallback, docs/real-data.md: bench calibrate builds it from the "
                     "calibration logs when they repeat one set-point cycle) rather than "
                     "against this model")
    unscored = not_scored(fit_scores, held, holdout)
    notes += [f"held-out {u['log']}: {u['signal']} not scored ({u['reason']}): only "
              f"{', '.join(u['scored']) or 'nothing'} judged on it" for u in unscored]
    return Calibration("actuator", {
        "model": "generic nut-level model (bench.sim.rigmodel)",
        "actuator": act.name, "motor_kind": act.motor_kind, "method": method,
        "actuator_description": act.to_dict(),
        "method_text": METHOD_TEXT[method], "sample_period_s": period_s,
        "values": values, "fitted": free, "ci95": ci, "start_costs": starts,
        "not_identified": [k for k, (lo, hi) in ci.items() if lo is None or hi is None
                           or (k not in LINEAR and hi > 10.0 * lo)],
        "described": {k: v for k, v in model_values(act).items() if v is not None},
        "fit_logs": [_src(t) for t in healthy], "fit_scores": fit_scores,
        "holdout_logs": [_src(t) for t in holdout], "holdout_scores": held,
        "holdout_summary": summary(held), "holdout_not_scored": unscored,
        "reaches_noise_floor": reach,
        "floor_factor": FLOOR_FACTOR, "notes": notes,
        "seconds": round(time.perf_counter() - t0, 3),
    }).to_dict()


def not_scored(fit_scores: Sequence[dict[str, Any]], held: Sequence[dict[str, Any]],
               holdout: Sequence[Trace]) -> list[dict[str, Any]]:
    """The signals scored on the calibration logs that a held-out log could not be scored
    on, with the reason (the log lacks the signal)."""
    fitted = sorted({s for sc in fit_scores for s in sc})
    out = []
    for sc, tr in zip(held, holdout, strict=True):
        for s in fitted:
            if s not in sc:
                why = (f"the log has no {s}" if not _has(tr, s) else
                       f"the model gives no {s} under this method")
                out.append({"log": _src(tr), "signal": s, "reason": why,
                            "scored": list(sc)})
    return out


METHOD_TEXT = {
    "fit-gains": "closed loop; the controller is unknown: a generic position/speed cascade "
                 "(saturation, sample time) fitted with the physical values",
    "measured-current": "no controller: the measured current drives the mechanics "
                        "(re-started from the measured position and speed every 0.5 s)",
    "described": "closed loop with the described controller; physical values fitted",
}


def _src(tr: Trace) -> str:
    return str(tr.meta.get("source", "?"))


def _reaches(scores: Sequence[dict[str, dict[str, float]]]) -> bool:
    return bool(scores) and all(v["ratio"] <= FLOOR_FACTOR for s in scores for v in s.values())


def summary(scores: Sequence[dict[str, dict[str, float]]]) -> dict[str, dict[str, float]]:
    """Per signal over logs: pooled RMS, mean floor, median and worst ratio."""
    out: dict[str, dict[str, float]] = {}
    for sig in sorted({s for sc in scores for s in sc}):
        rs = [sc[sig] for sc in scores if sig in sc]
        out[sig] = {"rms": float(np.sqrt(np.mean([r["rms"] ** 2 for r in rs]))),
                    "noise_floor": float(np.mean([r["noise_floor"] for r in rs])),
                    "ratio_median": float(np.median([r["ratio"] for r in rs])),
                    "ratio_max": float(np.max([r["ratio"] for r in rs]))}
    return out


def _fit_all(healthy: Sequence[Trace], act: Actuator, method: str, period_s: float,
             free: list[str], vals: dict[str, float | None]
             ) -> tuple[np.ndarray, dict[str, list[float | None]], list[float]]:
    """(theta, 95 % intervals, cost from each start) of the best of the fits from
    `STARTS` (one start unless gains are fitted)."""
    fl = [floors(t) for t in healthy]
    nx = 0 if method == "measured-current" else len(healthy)
    if not (free or nx):
        return _Fit(vals, free, _start(healthy, act)).theta(np.zeros(0)), {}, []
    best: tuple[float, Any, _Fit] | None = None
    costs = []
    for kp, wv in (STARTS if method == "fit-gains" else STARTS[:1]):
        fit = _Fit(vals, free, _start(healthy, act, kp, wv))
        lo, hi = fit.bounds()
        z0 = np.concatenate([fit.z0(), np.zeros(nx)])
        args = (fit, healthy, fl, act, method, period_s)
        sol = least_squares(_residual, z0, bounds=(np.append(lo, [-X0_FLOORS] * nx),
                                                   np.append(hi, [X0_FLOORS] * nx)),
                            args=args, max_nfev=200, diff_step=1e-3,
                            jac_sparsity=_sparsity(z0, len(free), args))
        costs.append(float(sol.cost))
        if best is None or sol.cost < best[0]:
            best = (float(sol.cost), sol, fit)
    assert best is not None
    _, sol, fit = best
    return fit.theta(sol.x[:len(free)]), _ci(sol, fit), costs


def _sparsity(z0: np.ndarray, nfree: int, args: tuple[Any, ...]) -> np.ndarray:
    """Which residuals each fitted value moves: the shared values all of them, a log's
    initial position only that log's (so finite differences perturb all initial
    positions at once)."""
    fit, traces, fl, act, method, period_s = args
    rows = [len(_residual(z0[:nfree], fit, [tr], [f], act, method, period_s))
            for tr, f in zip(traces, fl, strict=True)]
    sp = np.zeros((sum(rows), len(z0)), dtype=np.int8)
    sp[:, :nfree] = 1
    start = 0
    for k, r in enumerate(rows):
        if nfree + k < len(z0):
            sp[start:start + r, nfree + k] = 1
        start += r
    return sp


def _ci(sol: Any, fit: _Fit) -> dict[str, list[float | None]]:
    """95 % intervals from the Jacobian at the solution (Gauss-Newton covariance)."""
    j = sol.jac.toarray() if hasattr(sol.jac, "toarray") else np.asarray(sol.jac)
    dof = max(len(sol.fun) - len(sol.x), 1)
    s2 = 2.0 * sol.cost / dof
    try:
        cov = np.linalg.pinv(j.T @ j) * s2
    except np.linalg.LinAlgError:
        return {}
    out: dict[str, list[float | None]] = {}
    norms = np.linalg.norm(j, axis=0)
    for k, name in enumerate(fit.free):
        if not norms[k] > 1e-9 * max(float(norms.max()), 1e-300):
            out[name] = [None, None]      # no effect on the fit: not identified
            continue
        half = min(1.96 * math.sqrt(max(cov[k, k], 0.0)), 30.0)
        z = sol.x[k]
        lo, hi = (z - half, z + half) if name in LINEAR else (10 ** (z - half), 10 ** (z + half))
        out[name] = [float(lo), float(hi)]
    return out


def _notes(act: Actuator, method: str, period_s: float,
           vals: dict[str, float | None]) -> list[str]:
    notes = []
    if act.controller.get("sample_period_s") is None and method != "measured-current":
        notes.append(f"controller sample time unknown: the cascade runs every "
                     f"{period_s * 1e3:g} ms (not identified)")
    if act.motor_kind == "stepper_chopper":
        notes.append("stepper with a chopper drive: the model represents the load angle only "
                     "in its small-angle linear form (a stiffness and damping through the "
                     "cascade) and the logged current as offset + |force current|; the "
                     "chopper's current regulation, idle-current reduction, step/microstep "
                     "ripple and resonances are not represented")
    if act.values.get("load_sign") is None:
        notes.append("load sign unknown: a positive logged load is taken to push the nut "
                     "to +x (load_sign +1; not identified)")
    if act.controller.get("current_loop_tau_s") is None:
        notes.append("current loop taken as ideal (time constant 0): not identified")
    return notes
