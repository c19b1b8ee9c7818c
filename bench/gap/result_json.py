"""A diagnosis result (`bench.gap.diagnose.Result`) as JSON (`Result.json`): the ranking with each candidate's gap
before and after, its held-out shrink and scores, the localisation with the HUMS indexes
against nominal and against the verdict's model, the verdict and the finding."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.core.verdict import Level, Verdict
from bench.gap import effects as E
from bench.gap import families as F
from bench.gap.problem import Problem
from bench.gap.scores import excess, shrink_pct


def gap_summary(p: Problem, energies: dict[str, float]) -> dict[str, Any]:
    """A gap as the normalised RMS (1 = floor) plus the RMS of each signal in its unit."""
    tot = float(np.sqrt(np.mean(list(energies.values()))))
    return {"normalised": tot,
            "rms": {s: float(math.sqrt(max(e, 0.0)) * p.sigma[s]) for s, e in energies.items()}}


def _finite(x: Any) -> Any:
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items() if not str(k).startswith("_")}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return _finite(x.item())
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def to_json(r: Any) -> dict[str, Any]:
    """{"localisation", "ranking", "verdict"} with NaN as null."""
    h = r.holdout or r.problem
    healthy = {"energy": (r.localisation.get("heldout_excess") or {}).get("healthy_energy")}
    ranking = []
    for i, c in enumerate(r.ranking, 1):
        ranking.append({
            "rank": i,
            "effect": c.fit.name,
            "families": F.family_name(c.fit.name),
            "chosen": c is r.chosen,
            "params": c.fit.params_dict(),
            "gap_before": gap_summary(h, r.gap_before_heldout),
            "gap_after": gap_summary(h, c.heldout),
            "heldout_shrink_pct": shrink_pct(excess(r.gap_before_heldout, healthy),
                                             excess(c.heldout, healthy)),
            "score": {"bic": c.bic, "aic": c.aic},
            "suspect": c.suspect, "at_bound": c.edge,
        })
    loc = dict(r.localisation)
    if r.chosen is not None:
        loc["hums_indexes"] = hums_distance(r)
    return _finite({"localisation": loc, "ranking": ranking, "verdict": r.verdict,
                    "finding": r.finding})


def chosen_entry(js: dict[str, Any]) -> dict[str, Any] | None:
    """The ranking entry of the candidate the diagnosis chose (the ranking is by BIC; the
    chosen one need not be first), None without one."""
    return next((c for c in js.get("ranking", []) if c.get("chosen")), None)


def hums_distance(r: Any) -> dict[str, Any]:
    """The HUMS indexes of the held-out data against the nominal model and against the
    model with the verdict's effects: distance from nominal (Cp - 1, Ci - 1, ...)."""
    from bench.gap.indexes import indexes
    h = r.holdout
    p = r.problem
    if h is not None:
        tgt, lo, hi = h, 0, h.n
    else:
        tgt, lo, hi = p, p.n_fit, p.n
    before = tgt.info.get("nominal") or tgt.simulate()
    out: dict[str, Any] = {"before": indexes(tgt.meas, before, lo, hi, tgt.dt)}
    if r.chosen is not None:
        effs = [E.get(n) for n in r.chosen.fit.effects]
        after = tgt.simulate(effs, r.chosen.fit.theta)
        out["after"] = indexes(tgt.meas, after, lo, hi, tgt.dt)
    return out



GAP_KEYS = (
    # every diagnosis
    "log", "against", "reference", "verdict", "judged", "seconds",
    # against a model (the thesis plant, or a rig's calibrated generic model)
    "localisation", "ranking", "finding", "controller", "model", "rms_ratio", "threshold",
    "significant", "judged_on", "not_judged", "not_available", "indexes",
    # against a rig's healthy baseline
    "baseline", "load", "loads", "thresholds", "thresholds_by_load", "cycles",
    "judged_cycles", "flagged", "effects", "verdicts", "worst", "features",
    "phase_indexes", "notes",
)
"""The top-level keys of `bench gap --json`, whatever the log was judged against: the
keys a path has no value for are null. `verdict` is `bench.core.verdict.Verdict.to_json()`;
`against` is "model" or "baseline"; `reference` says what exactly."""


def gap_document(log: str, against: str, verdict: Verdict, details: dict[str, Any],
                 seconds: float | None = None) -> dict[str, Any]:
    """The one `bench gap --json` document (`GAP_KEYS`) of a diagnosis: `details` are the
    path's own keys (its effect-name ``verdict`` is the verdict's effect and is dropped)."""
    if against not in ("model", "baseline"):
        raise ValueError(f"against: model or baseline, not {against!r}")
    rest = {k: v for k, v in details.items() if k not in ("verdict", "against")}
    extra = sorted(set(rest) - set(GAP_KEYS))
    if extra:
        raise ValueError(f"keys outside the gap JSON schema: {', '.join(extra)}")
    out: dict[str, Any] = dict.fromkeys(GAP_KEYS)
    out.update(rest)
    out.update({"log": log, "against": against, "reference": verdict.reference,
                "verdict": verdict.to_json(), "judged": verdict.judged})
    if seconds is not None:
        out["seconds"] = seconds
    return out


def model_gap_verdict(js: dict[str, Any], reference: str) -> Verdict:
    """The thesis diagnosis' verdict (`to_json`): its effect is what the diagnosis named
    ("none": no significant gap, HEALTHY; a candidate or "unexplained": DEGRADED, the
    log is outside the noise floor of the model)."""
    effect = str(js["verdict"])
    sig = (js.get("localisation") or {}).get("significance") or {}
    ja = (sig.get("judged_against") or {}).get("line")
    reasons = [f"gap diagnosis: {effect}"] + ([ja] if ja else [])
    return Verdict(Level.HEALTHY if effect == "none" else Level.DEGRADED, effect,
                   tuple(reasons), reference)
