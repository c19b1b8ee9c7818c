"""A diagnosis result (`bench.gap.diagnose.Result`) as JSON (`Result.json`): the ranking with each candidate's gap
before and after, its held-out shrink and scores, the localisation with the HUMS indexes
against nominal and against the verdict's model, the verdict and the finding."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

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

