"""The model-form term of the verdict's intervals (docs/gap.md, "Intervals").

The sandwich intervals (`bench.gap.fit.intervals_cov`) hold the log's noise; the fast
model's error is taken off by `bench.gap.refine`. Neither holds the model family's own
misfit of an actuator whose physics it does not contain (a LuGre friction, a Hertzian
nut): that misfit is a bias, and a fit absorbs it into its parameters.

A calibration with held-out healthy logs (`bench calibrate --holdout`) has a log of the
actuator on which the true effect is none. The verdict's candidate fitted there departs
from its no-effect value by d (the fit's [0, 1] coordinates, one entry per free
parameter) through the model's form and the noise alone; no truth enters. d is taken as
one draw of a systematic error of zero mean and its outer product added to the fit's
covariance, cov_u + d d^T (in quadrature with the noise, as a type B uncertainty), and
the verdict's intervals follow from that covariance: its parameters' here. The friction
size is the family's one number whatever member fitted (`bench.gap.finding.
friction_size`), so its departure is taken in those terms: the healthy fit's friction
size s_h (1 at no effect), var ln(size) = the delta method through the noise's
covariance + ln(s_h)^2 (`size_departures`). Grid-searched parameters (delays) keep their
exact intervals. Without a healthy log the fit is returned as it is.

Cost: one fit of the verdict's candidate on the healthy log, and once per process the
healthy log's floors (`bench.gap.problem.build`, cached by log and model, CACHE_SIZE).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from bench.gap.fit import Fit, fit
from bench.gap.problem import Problem, build, fill_gaps
from bench.signals.trace import Trace
from plant_rt.params import PlantParams

RULE = ("cov_u + d d^T: d, the verdict's candidate fitted on the calibration's held-out "
        "healthy log minus its no-effect value ([0, 1] coordinates), added in quadrature "
        "to the fit's covariance; a friction size adds ln of the healthy fit's own friction "
        "size in quadrature instead; grid-searched parameters keep their exact intervals")

_CACHE: dict[tuple[Any, ...], tuple[Trace, PlantParams, Problem]] = {}
CACHE_SIZE = 4


def healthy_problem(trace: Trace, base: PlantParams, holdout_frac: float, bootstrap: int,
                    encoder: str, model: str, friction_split: str) -> Problem:
    """The healthy log's Problem against `base`, built as the diagnosis builds its log's
    (same fit fraction, floors, encoder, model and friction split); cached per process."""
    key = (id(trace), id(base), holdout_frac, bootstrap, encoder, model, friction_split)
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is trace and hit[1] is base:
        return hit[2]
    hp = build(fill_gaps(trace.measured(), "held-out healthy log"), base, holdout_frac,
               bootstrap=bootstrap, encoder=encoder, model=model,
               friction_split=friction_split, purpose="held-out healthy log")
    if len(_CACHE) >= CACHE_SIZE:        # a few calibrations per process at most
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = (trace, base, hp)
    return hp


def departure(p: Problem, f: Fit, healthy: Fit) -> np.ndarray:
    """d: per free parameter of `f` (order `f.free`), the healthy fit's value minus the
    no-effect value of `f`'s effects on `p`, in the parameter's [0, 1] coordinate."""
    d = np.zeros(len(f.free))
    for j, (i, name) in enumerate(f.free):
        prm = next(q for q in f.objs[i].params if q.name == name)
        v0 = f.objs[i].nominal(p.base)[name]
        vh = healthy.theta[i].get(name, v0)
        if not (math.isfinite(vh) and math.isfinite(v0)):
            continue
        d[j] = (prm.to_unit(min(max(vh, prm.lo), prm.hi))
                - prm.to_unit(min(max(v0, prm.lo), prm.hi)))
    return d


def widened(f: Fit, d: np.ndarray) -> Fit:
    """`f` with covariance cov_u + d d^T and its free parameters' intervals from it (as
    `bench.gap.fit._intervals` maps them: through each parameter's scale; a parameter the
    log did not move keeps its whole range); `f` itself when d is zero or `f` has no
    covariance."""
    if f.cov_u is None or not f.free or not np.any(d):
        return f
    cov = f.cov_u + np.outer(d, d)
    ci = [dict(c) for c in f.ci95]
    with np.errstate(invalid="ignore"):
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for j, (i, name) in enumerate(f.free):
        prm = next(q for q in f.objs[i].params if q.name == name)
        if ci[i].get(name) == (prm.lo, prm.hi) or not np.isfinite(sd[j]):
            continue                                 # not identifiable from this log
        u = prm.to_unit(min(max(f.theta[i][name], prm.lo), prm.hi))
        ci[i][name] = (prm.from_unit(u - 1.96 * sd[j]), prm.from_unit(u + 1.96 * sd[j]))
    return dataclasses.replace(f, cov_u=cov, ci95=ci)


def size_departures(hp: Problem, h: Fit) -> dict[int, float]:
    """ln of the friction size (`bench.gap.finding.friction_size`) of each friction-family
    effect of the healthy fit `h` on the healthy problem `hp`: the family's own size at no
    effect is 1, so this is its departure in the terms the verdict reports. The friction
    size's interval takes it instead of d d^T through its gradient: a member of several
    levels moves them against each other on the healthy log while their work stays
    near the model's, and d d^T would carry those moves to the fault's work."""
    from bench.gap.families import family
    from bench.gap.finding import friction_size
    out = {}
    for i, eff in enumerate(h.objs):
        if family(eff.name) == "friction":
            k = friction_size(hp, h, i)["factor"]
            if math.isfinite(k) and k > 0 and k != 1.0:
                out[i] = math.log(k)
    return out


def apply(p: Problem, f: Fit, reference: dict[str, Any] | None, nominal: PlantParams,
          holdout_frac: float, bootstrap: int, encoder: str, model: str,
          friction_split: str) -> tuple[Fit, dict[str, Any] | None]:
    """The verdict's fit `f` on `p` (built against `nominal`) with the model-form term of
    the calibration `reference` (its first held-out healthy log,
    ``reference["healthy_logs"]``), and what was done; (`f`, None) when the reference has
    no healthy log."""
    logs = (reference or {}).get("healthy_logs") or []
    if not logs:
        return f, None
    hp = healthy_problem(logs[0], nominal, holdout_frac, bootstrap, encoder, model,
                         friction_split)
    h = fit(hp, list(f.effects))
    if [sorted(t) for t in h.theta] != [sorted(t) for t in f.theta]:
        return f, {"applied": False, "why": "the healthy fit has other parameters"}
    d = departure(p, f, h)
    names = [name for _, name in f.free]
    g = widened(f, d)
    size = size_departures(hp, h) if g is not f else {}
    if size:
        g = dataclasses.replace(g, extra={**g.extra, "size_departure_ln": size,
                                          "cov_u_noise": f.cov_u})
    return g, {
        "healthy_friction_size": {h.effects[i]: math.exp(v) for i, v in size.items()},
        "applied": bool(np.any(d)), "rule": RULE,
        "healthy_log": ((reference or {}).get("healthy_names")
                        or (reference or {}).get("logs") or ["?"])[0],
        "healthy_fit": {k: float(v) for t in h.theta for k, v in t.items()},
        "departure_u": dict(zip(names, map(float, d), strict=True))}
