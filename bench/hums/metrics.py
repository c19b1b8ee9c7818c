"""Prognostic metrics of one run-to-failure run, with NASA's progpy (beyond the thesis).

Each `Prediction` (failure-time samples made at one time) becomes an `UnweightedSamples`
in a `ToEPredictionProfile`; `prognostic_horizon` (criterion: at least `beta` of the
samples within +-alpha of the true RUL), `alpha_lambda` at fractions of the true life,
and the relative accuracy RA = 1 - |RUL_true - RUL_pred| / RUL_true of the median
prediction (on the RUL: progpy's `relative_accuracy` is relative to the time of failure,
which flatters late predictions). The true failure is the thesis' Ci < 0.56 (section 6.5)
on the run's noise-free twin (`bench.hums.records.true_failure_time`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.hums.rul import Prediction


def score_run(preds: list[Prediction], t_warn: float, t_f: float, alpha: float = 0.2,
              lambdas: tuple[float, ...] = (0.5, 0.7, 0.9), beta: float = 0.5,
              cadence: float = 0.75) -> dict[str, Any]:
    """Prognostic metrics of one run with progpy: prognostic horizon (first time at least
    `beta` of the ToE samples lie within alpha of the true RUL), alpha-lambda at fractions
    `lambdas` of the true life, and relative accuracy of the median RUL there. A
    lambda point is scored on the first prediction within `cadence` after it (0.75 s for
    the 0.5 s command periods; one ground test a day: 1 day)."""
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
        near = [p for p in preds if t_l - 1e-9 <= p.t_pred_s <= t_l + cadence]
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


LAMBDAS = ("0.5", "0.7", "0.9")
"""The fractions of life `score_run` scores by default, as its keys spell them."""

LAMBDA_ROWS = [(f"alpha_lambda_{lam}", f"alpha-lambda met at {lam[2]}0 % of life",
                "{:.0%}") for lam in LAMBDAS] + \
              [(f"ra_{lam}_median", f"relative accuracy at {lam[2]}0 %, median", "{:.2f}")
               for lam in LAMBDAS]
"""Report rows (key, label, format) of `summarise_scores`' alpha-lambda and RA entries."""


def summarise_scores(rs: list[dict[str, Any]]) -> dict[str, float]:
    """Medians and shares over runs scored by `score_run` (at the default lambdas): the
    count, warned runs, warning time and horizons over life, runs with a horizon before
    half life, alpha-lambda met and the relative accuracy's median at each lambda."""
    def med(key: str) -> float:
        v = np.array([r.get(key, math.nan) for r in rs], dtype=float)
        return float(np.nanmedian(v)) if np.isfinite(v).any() else math.nan

    return {"runs": float(len(rs)),
            "warned_runs": float(np.mean([math.isfinite(r["t_warning_s"]) for r in rs])),
            "warning_life_frac_median": med("warning_life_frac"),
            "ph_life_frac_median": med("ph_life_frac"),
            "stable_ph_life_frac_median": med("stable_ph_life_frac"),
            "ph_before_half_life": float(np.mean([r["ph_life_frac"] >= 0.5 for r in rs])),
            **{f"alpha_lambda_{lam}": float(np.mean([bool(r.get(f"alpha_lambda_{lam}"))
                                                      for r in rs])) for lam in LAMBDAS},
            **{f"ra_{lam}_median": med(f"ra_{lam}") for lam in LAMBDAS}}
