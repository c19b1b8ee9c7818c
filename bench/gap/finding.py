"""What a verdict says in words: each effect's family, size and form, and its trouble
(docs/gap.md, "Candidate effects and their families" and "Fits that report their own trouble").

    friction x2.41 [2.22, 2.60] (Coulomb and static levels)
    backlash 50.0 um [49.9, 50.1]
    sensor delay 3 ms (LVDT, in the loop)

The size of a friction growth is one number whatever law the member fitted: the work the
fitted friction dissipates over the log's own motion against the work the model's
friction dissipates there (`bench.gap.resim.friction_work`), both re-simulated on the log
with every other effect of the candidate as fitted. For a pure scale of the friction
levels it is that scale (up to the change of motion it causes); for a viscous or a
Stribeck member it is what that law amounts to on this manoeuvre. Its interval is the
delta method through the fit's covariance (`bench.gap.fit.Fit.cov_u`), with the healthy
log's friction size in quadrature when the fit carries one (`bench.gap.modelform`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.gap import families as F
from bench.gap.fit import Fit
from bench.gap.problem import Problem
from bench.gap.resim import friction_work

STEP_U = 0.01
"""Finite-difference step of the friction size's gradient ([0, 1] coordinates)."""


def friction_size(p: Problem, f: Fit, i: int) -> dict[str, Any]:
    """The friction growth of effect `i` of fit `f` on `p` (module doc): {"factor",
    "ci95", "how"}; the factor is NaN when the log is re-simulated without a loop (the
    measured-current path has no single run to account the work over)."""
    objs = f.objs
    nom = objs[i].nominal(p.base)

    def work(theta_i: dict[str, float]) -> float:
        th = [dict(t) for t in f.theta]
        th[i] = theta_i
        params = p.params_for(objs, th)
        return friction_work(params, p.drive, p.n_fit, p.loop_delays(objs, th))

    w0 = work({k: nom.get(k, v) for k, v in f.theta[i].items()})
    w = work(dict(f.theta[i]))
    out: dict[str, Any] = {"factor": float("nan"), "ci95": [None, None],
                           "how": "friction work over the log's motion, fitted / model's"}
    if not (math.isfinite(w0) and w0 > 0 and math.isfinite(w)):
        return out
    factor = w / w0
    out["factor"] = factor
    free = [(j, name) for j, (k, name) in enumerate(f.free) if k == i]
    if f.cov_u is None or not free:
        return out
    grad = np.zeros(len(f.free))
    prms = {q.name: q for q in objs[i].params}
    for j, name in free:
        prm = prms[name]
        u = prm.to_unit(f.theta[i][name])
        h = STEP_U if u + STEP_U <= 1.0 else -STEP_U
        th = dict(f.theta[i])
        th[name] = prm.from_unit(u + h)
        grad[j] = (work(th) / w0 - factor) / h
    # the model-form term in the size's own terms (`bench.gap.modelform.size_departures`)
    form = (f.extra.get("size_departure_ln") or {}).get(i)
    cov = f.cov_u if form is None else f.extra["cov_u_noise"]
    var = float(grad @ cov @ grad)
    if math.isfinite(var) and var >= 0 and factor > 0:
        sd = math.sqrt(var) / factor                    # on ln(factor)
        if form is not None:
            sd = math.sqrt(sd ** 2 + form ** 2)
        out["ci95"] = [factor * math.exp(-1.96 * sd), factor * math.exp(1.96 * sd)]
    return out


def describe(p: Problem, f: Fit, suspect: list[str], edge: list[str]) -> dict[str, Any]:
    """The finding of candidate fit `f`: per effect its family, form and size, the
    candidate's trouble and the one line the console prints."""
    parts, effects = [], []
    pd = f.params_dict()
    for i, eff in enumerate(f.objs):
        fam = F.family(eff.name)
        entry: dict[str, Any] = {"effect": eff.name, "family": fam,
                                 "form": F.SUBFORM.get(eff.name, eff.name)}
        own = {q.name: pd[q.name] for q in eff.params if q.name in pd}
        shown = {k: v for k, v in own.items() if k != "nut_friction_share"}
        if fam == "friction":
            fs = friction_size(p, f, i)
            entry["size"] = {"kind": "factor", "value": fs["factor"], "ci95": fs["ci95"],
                             "nominal": 1.0, "how": fs["how"]}
            text = _factor_text(fs)
        else:
            entry["size"] = size_of(p, eff, own)
            text = _values_text(shown)
            if eff.name == "backlash" and entry["size"]["kind"] == "preload_n":
                fam = entry["family"] = "preload"
                entry["form"] = "a wear clearance the interference preload took up"
                s = entry["size"]
                lo, hi = s["ci95"]
                ci = f" [{lo:.4g}, {hi:.4g}]" if lo is not None and hi is not None else ""
                text = (f"{s['value']:.4g} N{ci} left of {s['nominal']:.4g} N (clearance "
                        f"{s['backlash_m'] * 1e6:.3g} um, no free play)")
            elif eff.name == "backlash" and entry["size"]["value"] is not None:
                text += f", axial lost motion {entry['size']['value'] * 1e6:.3g} um"
        share = own.get("nut_friction_share")
        if share is not None and share.get("value") is not None:
            entry["nut_friction_share"] = share["value"]     # where the friction acts
        entry["line"] = f"{F.LABEL.get(fam, fam)} {text}".rstrip()
        if entry["form"] != eff.name or fam != eff.name:
            entry["line"] += f" ({entry['form']})"
        effects.append(entry)
        parts.append(entry["line"])
    fams = "+".join(sorted({e["family"] for e in effects}))
    out: dict[str, Any] = {"families": fams, "effects": effects,
                           "suspect": suspect, "at_bound": edge,
                           "line": " + ".join(parts)}
    if edge:
        out["edge_note"] = F.EDGE_NOTE
    return out


def holds_no_effect(p: Problem, f: Fit, i: int) -> bool | None:
    """Whether the 95 % interval of effect `i` of fit `f` holds the effect's no-effect
    value (the model's: a friction factor 1, a delay, a backlash or an offset 0, a gain
    1): for a friction member the friction growth's interval (`friction_size`, as the
    finding reports it), otherwise every fitted parameter's but the nut friction share
    (where a friction acts, not how large an effect is); an interval open on a bound
    runs on to infinity. None when an interval is unknown."""
    eff = f.objs[i]
    if F.family(eff.name) == "friction":
        lo, hi = friction_size(p, f, i)["ci95"]
        if lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi):
            return bool(lo <= 1.0 <= hi)
    nom = eff.nominal(p.base)
    side = f.at_bound[i] if f.at_bound else {}
    held = []
    for q in eff.params:
        if q.name == "nut_friction_share" or q.name not in f.ci95[i]:
            continue
        lo, hi = f.ci95[i][q.name]
        lo = -math.inf if side.get(q.name) == "lower" else lo
        hi = math.inf if side.get(q.name) == "upper" else hi
        if not (math.isfinite(nom.get(q.name, math.nan)) and lo == lo and hi == hi):
            return None
        held.append(lo <= nom[q.name] <= hi)
    return all(held) if held else None


def insignificant(p: Problem, f: Fit) -> list[str]:
    """The effects of fit `f` after its first whose interval holds their no-effect value
    (`holds_no_effect`): added to the first, not told apart from no effect."""
    out = []
    for i in range(1, len(f.objs)):
        try:
            if holds_no_effect(p, f, i):
                out.append(f.objs[i].name)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError):
            continue
    return out


def faint(p: Problem, f: Fit) -> list[str]:
    """The effects of fit `f` after its first that no logged signal shows above the
    diagnosis's floor: the RMS over the whole log of `f`'s re-simulation less the same
    without the effect, over the signal's floor `p.sigma`, below 1 on every signal (the
    benchmarks' "above the floor" test, on the verdict's side: docs/gap.md, "Selection"
    rule 3)."""
    out: list[str] = []
    trouble = (ValueError, FloatingPointError, np.linalg.LinAlgError)
    try:
        whole = p.simulate(f.objs, f.theta)
    except trouble:                       # no re-simulation: nothing judged faint
        return out
    for i in range(1, len(f.objs)):
        keep = [k for k in range(len(f.objs)) if k != i]
        try:
            less = p.simulate([f.objs[k] for k in keep], [f.theta[k] for k in keep])
        except trouble:
            continue
        shown = [float(np.sqrt(np.mean((whole[s] - less[s]) ** 2))) / p.sigma[s]
                 for s in p.sigma if s in whole and s in less and p.sigma[s] > 0]
        if shown and max(shown) < 1.0:
            out.append(f.objs[i].name)
    return out


def _factor_text(size: dict[str, Any]) -> str:
    k = size.get("factor")
    if k is None or not math.isfinite(k):
        return "grown"
    lo, hi = size.get("ci95") or [None, None]
    ci = f" [{lo:.3g}, {hi:.3g}]" if lo is not None and hi is not None else ""
    return f"x{k:.3g}{ci}"


def _values_text(params: dict[str, dict[str, Any]]) -> str:
    from bench.gap.summary import fmt_params
    return fmt_params(params, names=False)


KIND = {"sensor_delay_s": "delay_s", "lvdt_delay_s": "delay_s", "encoder_delay_s": "delay_s",
        "log_skew_s": "delay_s", "lvdt_delay_log_s": "delay_s",
        "encoder_delay_log_s": "delay_s", "current_delay_log_s": "delay_s",
        "current_offset_a": "current_offset_a", "current_offset_log_a": "current_offset_a"}
"""Parameters whose sizes compare across the members of their family (a delay in
seconds wherever the sensor is late; a current offset in A on either sensor)."""
ABSOLUTE = ("lost_motion_m", "delay_s", "current_offset_a", "lvdt_offset_m",
            "lvdt_lag_s")
"""Size kinds compared as values (their no-effect value is 0); the others as the ratio
to the model's value."""


def size_of(p: Problem, eff: Any, own: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """A non-friction effect's size: its first parameter, in a kind that compares across
    its family (`KIND`), with the model's value; a backlash as the axial clearance (the
    parameter is along the contact normal, eq. 5.19-5.24: over g = cos(alpha) sin(beta))."""
    name = eff.params[0].name
    d = own.get(name, {})
    v = d.get("value")
    lo, hi = d.get("ci95") or [None, None]
    nominal = eff.nominal(p.base).get(name)
    if eff.name == "backlash":
        def lm(b: float | None) -> float | None:
            return None if b is None else lost_motion(p.base, b)
        free = lm(v)
        fpr = p.base.effects.preload_n
        if free is not None and free <= 0.0 and p.base.screw.preload_by_interference \
                and fpr > 0.0 and v is not None and v > 0.0:
            def left(b: float | None) -> float | None:
                return None if b is None else preload_left(p.base, b)
            a, b = left(hi), left(lo)               # the preload falls as b grows
            return {"kind": "preload_n", "value": left(v), "ci95": [a, b], "nominal": fpr,
                    "backlash_m": v}
        return {"kind": "lost_motion_m", "value": free, "ci95": [lm(lo), lm(hi)],
                "nominal": 0.0, "backlash_m": v}
    return {"kind": KIND.get(name, name), "value": v, "ci95": [lo, hi], "nominal": nominal}


def preload_left(base: Any, backlash_m: float) -> float:
    """The preload (N) an interference-preloaded nut keeps with a wear clearance
    `backlash_m` (`plant_rt.contacts.worn_nut`)."""
    from plant_rt.contacts import contact_geometry, hertz_reference, worn_nut
    kstar, mslope, z, g = contact_geometry(base)
    return float(worn_nut(base.effects.preload_n, backlash_m, kstar, mslope, z, g,
                          hertz_reference(base))[0])


def lost_motion(base: Any, backlash_m: float) -> float:
    """The axial lost motion (m) a backlash `backlash_m` (along the contact normal, as
    `effects.backlash_m`) gives the model `base`: b / g, g = cos(alpha) sin(beta) (eq.
    5.26); on a double nut preloaded by an interference (`screw.preload_by_interference`)
    what the clearance leaves after eating the interference (`plant_rt.contacts.worn_nut`,
    thesis section 2.3). What the log shows of a backlash: the free play."""
    from plant_rt.contacts import contact_geometry, hertz_reference, worn_nut
    kstar, mslope, z, g = contact_geometry(base)
    b = backlash_m
    if base.screw.preload_by_interference:
        b = worn_nut(base.effects.preload_n, backlash_m, kstar, mslope, z, g,
                     hertz_reference(base))[1]
    return float(b / g)


def relative_error(size: dict[str, Any], truth_kind: str, truth: float,
                   truth_nominal: float) -> float | None:
    """How far a found size is from the truth, relative to the truth's own departure from
    its no-effect value: |found - truth| / |truth - none|, each as a value (`ABSOLUTE`
    kinds) or as the ratio to its own model's value (a calibrated lead of 3.98 mm found
    at 4.02 against a true 4.0 -> 4.04: the ratios 1.010 and 1.010). None when the
    kinds differ or a value is missing."""
    v = size.get("value")
    if size.get("kind") != truth_kind or v is None or not math.isfinite(v):
        return None
    if truth_kind in ABSOLUTE:
        dev_true, dev_found = truth - truth_nominal, v - (size.get("nominal") or 0.0)
    else:
        v0 = size.get("nominal")
        if not v0 or not truth_nominal:
            return None
        dev_true, dev_found = truth / truth_nominal - 1.0, v / v0 - 1.0
    if dev_true == 0.0:
        return None
    return abs(dev_found - dev_true) / abs(dev_true)


def covers(size: dict[str, Any], truth_kind: str, truth: float, truth_nominal: float
           ) -> bool | None:
    """Whether the found size's interval holds the truth (in the same terms as
    `relative_error`); None when it cannot say."""
    lo, hi = size.get("ci95") or [None, None]
    if size.get("kind") != truth_kind or lo is None or hi is None:
        return None
    if truth_kind in ABSOLUTE:
        t = truth - truth_nominal + (size.get("nominal") or 0.0)
    else:
        v0 = size.get("nominal")
        if not v0 or not truth_nominal:
            return None
        t = truth / truth_nominal * v0
    return bool(lo <= t <= hi)
