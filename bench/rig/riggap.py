"""The gap of a log against another actuator's calibrated generic model.

`bench gap LOG --nominal CAL.json` with a calibration from `bench calibrate --actuator`
(`bench.rig.rigcal`) comes here: the thesis plant's diagnosis needs signals and a SYNC
rate such logs do not have (`bench.gap.needs`); this one needs only the set-point, the
position and, for the current's parts, the current, at any rate.

- localisation: the residual energy of each signal against its floor at the log's own
  instants, E_s = mean(r_s^2) / sigma_s^2, its excess above 1 split by regime
  (start/stop within 0.2 s of the set-point starting or stopping, cruise, dwell), by
  direction (extend, retract) and by nut position (10 bins across the travel);
- HUMS indexes against the calibrated model as the monitoring model: Cp, Ci
  (eq. 6.5-6.6, ratios of integrals), mean position error (6.4), peak-current ratio (6.7);
- ranking: each candidate effect re-fits its values of the generic model on the log
  (friction, force gain, current offset, inertia, controller, a position-locked
  resistance), ranked by BIC; the verdict is the best candidate when it lowers the BIC
  by more than `BIC_MARGIN`, and "no significant gap" when no signal's RMS exceeds the
  threshold: the larger of `rigcal.FLOOR_FACTOR` and the worst ratio the calibration's
  held-out healthy logs left (a model that does not reach the floor on healthy logs
  must not call every log faulty). The threshold comes from the healthy logs only.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from bench import BenchError
from bench.gap.inputs import Calibration
from bench.hums import formulas as F
from bench.rig import rigcal as RC
from bench.rig.actuator import Actuator, from_dict
from bench.signals import estimators as E
from bench.signals.trace import Trace
from bench.sim import rigmodel as RM

CANDIDATES: dict[str, tuple[str, ...]] = {
    "friction": ("coulomb_n", "viscous_n_s_per_m"),
    "force_gain": ("force_per_a_n",),
    "current_offset": ("current_offset_a",),
    "inertia": ("mass_kg",),
    "controller": ("kp_1_s", "kv_a_s_per_m"),
    "localised_resistance": ("bump_n", "bump_at_m"),
}
"""Candidate effects: the generic model's values each one re-fits."""
DOC = {
    "friction": "friction level (Coulomb and viscous)",
    "force_gain": "force per ampere (torque constant, drive gain)",
    "current_offset": "current sensor offset",
    "inertia": "moving mass / inertia",
    "controller": "controller gains",
    "localised_resistance": "a resistance at one nut position (spall, dent, debris)",
}
NEEDS = ("setpoint_position_m", "position_m")
CURRENT_EFFECTS = ("current_offset",)
"""Effects that act only through the logged current (the model's current offset is added
to its logged current, nothing else): ranked only on a log with current_a."""
BIC_MARGIN = 10.0
NBINS = 10


def is_rig_doc(data: Any) -> bool:
    """Whether a JSON object is a calibration of `bench calibrate --actuator` (kind
    "actuator", `bench.gap.inputs.Calibration`)."""
    cal = Calibration.of(data)
    return cal is not None and cal.kind == "actuator"


def calibration_of(cal: dict[str, Any], path: str | Path) -> tuple[dict[str, Any], Actuator]:
    """A generic calibration's object (read once by the caller) and its actuator; one
    without an actuator description is a one-line BenchError."""
    desc = cal.get("actuator_description")
    if not isinstance(desc, dict):
        raise BenchError(f"{path}: a calibration of another actuator needs its "
                         "\"actuator_description\" (bench calibrate --actuator writes it)")
    check_values(cal, path)
    return cal, from_dict(desc, str(path))


def check_values(cal: dict[str, Any], path: str | Path) -> None:
    """The model values, method and sample period a generic calibration is re-simulated
    with (`rigcal.theta_of`, `rigcal.simulate`): a one-line BenchError naming the field
    that is missing or not a number."""
    redo = "re-run bench calibrate --actuator"
    vals = cal.get("values")
    if not isinstance(vals, dict):
        raise BenchError(f"{path}: no \"values\" object (the calibrated model values; "
                         f"{redo})")
    for k in RM.THETA:
        if k not in vals and k in RM.EXTRA:
            continue
        v = vals.get(k)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise BenchError(f"{path}: values.{k} must be a finite number, got "
                             f"{'nothing' if k not in vals else repr(v)} ({redo})")
    if cal.get("method") not in RC.NEEDS and cal.get("method") != "described":
        raise BenchError(f"{path}: method must be one of {', '.join(RC.NEEDS)}, described; "
                         f"got {cal.get('method')!r} ({redo})")
    per = cal.get("sample_period_s")
    if isinstance(per, bool) or not isinstance(per, (int, float)) or not per > 0 \
            or not math.isfinite(per):
        raise BenchError(f"{path}: sample_period_s must be a number of seconds > 0, got "
                         f"{per!r} ({redo})")


def _regimes(tr: Trace) -> dict[str, np.ndarray]:
    t = tr.t
    sp = np.nan_to_num(tr["setpoint_position_m"])
    v = np.gradient(sp, t)
    moving = E.motion_direction(v, E.moving_threshold(v)) != 0
    edge = np.zeros(len(t), bool)
    for k in np.flatnonzero(np.diff(moving.astype(int)) != 0):
        edge |= np.abs(t - t[k]) <= 0.2
    return {"start_stop": edge, "cruise": moving & ~edge, "dwell": ~moving & ~edge,
            "extend": moving & (v > 0), "retract": moving & (v < 0)}


def _shares(r2: np.ndarray, masks: dict[str, np.ndarray]) -> dict[str, float]:
    ex = np.clip(r2 - 1.0, 0.0, None)
    tot = float(ex.sum())
    return {k: (float(ex[m].sum()) / tot if tot > 0 else 0.0) for k, m in masks.items()}


def localise(tr: Trace, sim: dict[str, np.ndarray], fl: dict[str, float]) -> dict[str, Any]:
    """Residual energy per signal, its excess by regime, direction and nut position."""
    reg = _regimes(tr)
    pos = np.asarray(tr["position_m"], float)
    lo, hi = float(np.nanmin(pos)), float(np.nanmax(pos))
    edges = np.linspace(lo, hi, NBINS + 1)
    out: dict[str, Any] = {"energy": {}, "regimes": {}, "direction": {}, "position_mm": {}}
    for s, y in sim.items():
        r2 = np.nan_to_num(((np.asarray(tr[s], float) - y) / fl[s]) ** 2, nan=0.0)
        out["energy"][s] = float(np.mean(r2))
        out["regimes"][s] = _shares(r2, {k: reg[k] for k in ("start_stop", "cruise", "dwell")})
        out["direction"][s] = _shares(r2, {k: reg[k] for k in ("extend", "retract")})
        bins = {f"{edges[b] * 1e3:.0f}-{edges[b + 1] * 1e3:.0f}":
                (pos >= edges[b]) & (pos <= edges[b + 1]) for b in range(NBINS)}
        out["position_mm"][s] = _shares(r2, bins)
    return out


def indexes(tr: Trace, sim: dict[str, np.ndarray]) -> dict[str, float]:
    """The HUMS indexes with the calibrated model as the monitoring model."""
    ok = np.isfinite(tr["position_m"]) & np.isfinite(sim["position_m"])
    out = {"cp": F.cp(sim["position_m"][ok], tr["position_m"][ok]),
           "mean_error_m": F.mean_error(sim["position_m"][ok], tr["position_m"][ok])}
    if "current_a" in sim:
        okc = np.isfinite(tr["current_a"]) & np.isfinite(sim["current_a"])
        out["ci"] = F.ci(sim["current_a"][okc], tr["current_a"][okc])
        out["peak_ratio"] = F.peak_ratio(sim["current_a"][okc], tr["current_a"][okc])
    return out


def _fit_candidate(tr: Trace, act: Actuator, cal: dict[str, Any], names: tuple[str, ...],
                   fl: dict[str, float], start_at: float) -> tuple[float, dict[str, float]]:
    """(sum of squared normalised residuals, fitted values) of one candidate on `tr`."""
    base = {**RM.EXTRA, **cal["values"]}
    method, period = cal["method"], cal["sample_period_s"]
    scale = max(abs(base["coulomb_n"]), 0.1 * abs(base["force_per_a_n"]), 1.0)
    lin = {"bump_n": (0.0, -2.0 * scale, 5.0 * scale),
           "bump_at_m": (start_at, start_at - 0.02, start_at + 0.02),
           "current_offset_a": (base["current_offset_a"], base["current_offset_a"] - 5.0,
                                base["current_offset_a"] + 5.0)}
    z0, lo, hi = [], [], []
    for n in names:
        if n in lin:
            a, b, c = lin[n]
        else:
            a = math.log10(max(base[n], 1e-9))
            b, c = a - 2.0, a + 2.0
        z0.append(a)
        lo.append(b)
        hi.append(c)
    z0.append(0.0)
    lo.append(-RC.X0_FLOORS)
    hi.append(RC.X0_FLOORS)

    def values(z: np.ndarray) -> dict[str, float]:
        v = dict(base)
        for n, zi in zip(names, z, strict=False):
            v[n] = float(zi) if n in lin else float(10.0 ** zi)
        return v

    def resid(z: np.ndarray) -> np.ndarray:
        th = np.array([values(z)[k] for k in RM.THETA])
        sim = RC.simulate(th, tr, act, method, period, float(z[-1]) * fl["position_m"])
        parts = [np.nan_to_num((np.asarray(tr[s], float) - y) / fl[s], nan=1e3)
                 for s, y in sim.items()]
        return np.clip(np.concatenate(parts), -1e4, 1e4)

    sol = least_squares(resid, np.array(z0), bounds=(np.array(lo), np.array(hi)),
                        max_nfev=60, diff_step=1e-3, x_scale="jac")
    v = values(sol.x)
    return float(np.sum(sol.fun ** 2)), {n: v[n] for n in names}


def model_signals(tr: Trace, cal: dict[str, Any], act: Actuator
                  ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """(the calibrated model's signals at `tr`'s instants, `tr`'s noise floor per signal);
    the closed loop's initial nut position fitted within the first sample's noise."""
    theta = RC.theta_of(cal)
    method, period = cal["method"], cal["sample_period_s"]
    sim = RC.simulate(theta, tr, act, method, period,
                      RC.fit_x0(theta, tr, act, method, period))
    return sim, RC.floors(tr)


def rms_ratios(tr: Trace, sim: dict[str, np.ndarray], fl: dict[str, float]
               ) -> dict[str, float]:
    """RMS residual / noise floor per signal (the measured samples only)."""
    out = {}
    for s, y in sim.items():
        r = (np.asarray(tr[s], float) - y) / fl[s]
        r = r[np.isfinite(r)]
        out[s] = float(np.sqrt(np.mean(r ** 2))) if len(r) else float("nan")
    return out


def thresholds(cal: dict[str, Any], ratios: dict[str, float]) -> dict[str, float]:
    """Per signal: the larger of `rigcal.FLOOR_FACTOR` and the worst ratio the
    calibration's held-out healthy logs left (its calibration logs without any)."""
    healthy = cal.get("holdout_summary") or RC.summary(cal.get("fit_scores", []))
    return {s: max(RC.FLOOR_FACTOR, healthy.get(s, {}).get("ratio_max", 0.0)) for s in ratios}


def diagnose_rig(tr: Trace, cal: dict[str, Any], act: Actuator,
                 candidates: tuple[str, ...] = tuple(CANDIDATES)) -> dict[str, Any]:
    """Localisation, indexes, ranking and verdict of `tr` against `cal` (module doc)."""
    t0 = time.perf_counter()
    needs = dict.fromkeys(NEEDS + RC.NEEDS.get(str(cal.get("method")), ()))
    lack = [s for s in needs if s not in tr or not np.isfinite(tr[s]).any()]
    if lack:
        raise BenchError(f"the gap against a generic calibration not available: needs "
                         f"{', '.join(lack)}")
    short = RC.too_short(tr)
    if short:
        raise BenchError(f"{tr.meta.get('source', 'log')}: the gap against a generic "
                         f"calibration not available: {short}")
    sim, fl = model_signals(tr, cal, act)
    loc = localise(tr, sim, fl)
    ratios = {s: math.sqrt(e) for s, e in loc["energy"].items()}
    thr = thresholds(cal, ratios)
    unjudged = not_judged(cal, ratios)
    why = unjudged.get("current_a", "the log has no current_a")
    absent = {e: f"not available: needs current_a ({why})"
              for e in candidates if e in CURRENT_EFFECTS and "current_a" not in ratios}
    candidates = tuple(e for e in candidates if e not in absent)
    significant = any(ratios[s] > thr[s] for s in ratios)
    n = sum(int(np.isfinite(tr[s]).sum()) for s in ratios)
    rss0, _ = _fit_candidate(tr, act, cal, (), fl, 0.0)
    bic0 = n * math.log(max(rss0, 1e-300) / n)
    pos_bins = loc["position_mm"].get("current_a", loc["position_mm"]["position_m"])
    worst = max(pos_bins, key=lambda k: pos_bins[k])
    start_at = 1e-3 * float(np.mean([float(x) for x in worst.split("-")]))
    ranking: list[dict[str, Any]] = []
    for name in candidates:
        rss, vals = _fit_candidate(tr, act, cal, CANDIDATES[name], fl, start_at)
        k = len(CANDIDATES[name])
        bic = n * math.log(max(rss, 1e-300) / n) + k * math.log(n)
        ranking.append({"effect": name, "doc": DOC[name], "values": vals,
                        "delta_bic": bic - bic0, "rms_ratio_after": math.sqrt(rss / n)})
    ranking.sort(key=lambda r: r["delta_bic"])
    best = ranking[0] if ranking else None
    if not significant:
        verdict = "no significant gap"
    elif best is not None and best["delta_bic"] < -BIC_MARGIN:
        verdict = best["effect"]
    else:
        verdict = "unexplained"
    return {"model": "generic nut-level model, calibrated (bench calibrate --actuator)",
            "baseline": f"calibration of {act.name} on {len(cal.get('fit_logs', []))} "
                        "healthy log(s)",
            "rms_ratio": ratios, "threshold": thr, "significant": significant,
            "judged_on": list(ratios), "not_judged": unjudged, "not_available": absent,
            "localisation": loc, "indexes": indexes(tr, sim), "ranking": ranking,
            "verdict": verdict, "seconds": round(time.perf_counter() - t0, 3)}


def not_judged(cal: dict[str, Any], ratios: dict[str, float]) -> dict[str, str]:
    """The signals the calibration was scored on (its healthy logs) that the log could not
    be judged on, with the reason (the log has none)."""
    healthy = cal.get("holdout_summary") or RC.summary(cal.get("fit_scores", []))
    return {s: f"the log has no {s}" for s in healthy if s not in ratios}


def judged_text(js: dict[str, Any]) -> str:
    """Which signals the diagnosis judged, and which of the calibration's it could not."""
    out = "judged on " + ", ".join(js["judged_on"])
    if js.get("not_judged"):
        out += " only; not judged: " + "; ".join(f"{s} ({why})"
                                                for s, why in js["not_judged"].items())
    return out


def text(js: dict[str, Any]) -> str:
    """The diagnosis in a few lines."""
    lines = [f"against: {js['baseline']}"]
    for s, r in js["rms_ratio"].items():
        reg = js["localisation"]["regimes"][s]
        where = max(reg, key=lambda k: reg[k])
        lines.append(f"  {s:12s} RMS {r:.2f} x floor (threshold {js['threshold'][s]:.2f}); "
                     f"most excess in {where} ({100 * reg[where]:.0f} %)")
    lines.append("  indexes: " + ", ".join(f"{k} {v:.4g}" for k, v in js["indexes"].items()))
    for i, r in enumerate(js["ranking"][:4], start=1):
        vals = "; ".join(f"{k} = {v:.4g}" for k, v in r["values"].items())
        lines.append(f"  {i}. {r['effect']:21s} dBIC {r['delta_bic']:9.1f}  {vals}")
    for e, why in js.get("not_available", {}).items():
        lines.append(f"  {e}: {why}")
    lines.append(f"verdict: {js['verdict']} (baseline: {js['baseline']}); {judged_text(js)}")
    return "\n".join(lines)
