"""The run-to-failure campaign (beyond the thesis): randomised RUL runs and healthy runs,
the thesis' algorithm (section 6.5) and the fused predictor scored on them with progpy,
and the campaign's table, JSON and figure.

Each run-to-failure run draws its schedule (duration, growth rates, start preload,
preload decay; `CAMPAIGN_RANGES`) and noise seed, and has a noise-free twin for its true
failure time (Ci, eq. 6.6, below 0.56). Healthy runs (no backlash, friction +-10 %,
preload held) measure false alarms. Methods: the thesis' cubic on Ci and on Ci over 15
harmonics (`bench.hums.rul`), the fused predictor (`bench.hums.fusion`); metrics
`bench.hums.metrics`. The runs go to the worker pool (`bench.runtime.workers.run_all`), longest
first.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError, machine_description
from bench.core.jsonsafe import json_safe
from bench.hums import monitor as M
from bench.hums.calibration import calibrate, healthy_params
from bench.hums.fusion import Calibration, FusedPredictor, causal_median, fused_backlash
from bench.hums.metrics import LAMBDA_ROWS, score_run, summarise_scores
from bench.hums.records import RunRecord, simulate_record, true_failure_time
from bench.hums.rul import N_BOOT, WARNING, Prediction, thesis_predict, thesis_profile
from bench.runtime.workers import run_all
from plant_rt.params import PlantParams
from plant_rt.paramvalues import seed_in_range

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
                 "sensors.noise_seed": seed_in_range(seed)})
    return base.with_dict(vals)


def _campaign_run(job: tuple[str, float, bool]) -> dict[str, Any]:
    """Worker: one run (JSON plant parameters), and its noise-free twin unless healthy."""
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
    """One run-to-failure run: its drawn parameters, true failure time and scores."""
    index: int
    params: dict[str, float]
    t_failure_s: float
    per_method: dict[str, dict[str, Any]]


@dataclass
class CampaignResult:
    """Scores, false alarms, summary, the calibration used and an example run."""
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
    """Warning time and predictions of `method` on one run."""
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
    b = causal_median(fused_backlash(rec.table, cal), 3)
    return np.asarray(b > cal.warn_um) & (t > 0)


def run_campaign(n_runs: int = 20, n_healthy: int = 10, seed: int = 2024,
                 params: PlantParams | None = None, workers: int | None = None,
                 progress: bool = True, cal: Calibration | None = None,
                 scheduler: str | None = None) -> CampaignResult:
    """`n_runs` run-to-failure runs (randomised schedules and noise seeds, each with a
    noise-free twin for its true failure time) and `n_healthy` healthy runs (false
    alarms), scored for the thesis algorithm (on Ci and on harmonic Ci) and the fused
    predictor with progpy's metrics."""
    if n_runs < 1:
        raise BenchError("the campaign needs at least one run-to-failure run")
    t0 = time.perf_counter()
    base = params or PlantParams()
    kp = M.fitted(base)[0].gain_rad_s_per_m
    cal = cal or calibrate(base, kp, workers=workers, progress=progress,
                           scheduler=scheduler)
    rng = np.random.default_rng(seed)
    run_params = [campaign_params(base, rng, seed * 1000 + k) for k in range(n_runs)]
    healthy = [healthy_params(base, rng, seed * 1000 + 500 + k).with_dict(
        {"schedule.duration_s": 120.0}) for k in range(n_healthy)]
    jobs = [(p.to_json(), kp, False) for p in run_params]
    jobs += [(p.to_json(), kp, True) for p in healthy]
    results = _longest_first(jobs, workers, progress, scheduler)
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
    healthy_alarm = _healthy_alarm([r["record"] for r in results[n_runs:]], cal)
    res = CampaignResult(scores, healthy_alarm, _summary(scores, healthy_alarm), cal,
                         time.perf_counter() - t0, n_runs, n_healthy, machine_description())
    ex = next((s for s in scores if math.isfinite(s.t_failure_s)), None)
    if ex is not None:
        res.example = _example(ex, results[ex.index]["record"], cal, seed)
    return res


def _longest_first(jobs: list[tuple[str, float, bool]], workers: int | None,
                   progress: bool, scheduler: str | None = None) -> list[dict[str, Any]]:
    """The runs on the worker pool, longest first (keeps both workers busy to the end; a
    failing run also runs its twin); results in job order."""
    cost = [120.0 if healthy else 2.0 * PlantParams.from_json(pj).schedule.duration_s
            for pj, _, healthy in jobs]
    order = sorted(range(len(jobs)), key=lambda k: -cost[k])
    got = run_all(_campaign_run, [jobs[k] for k in order], workers, progress,
                  desc="hums campaign", unit="run", scheduler=scheduler)
    results: list[Any] = [None] * len(jobs)
    for k, r in zip(order, got, strict=True):
        results[k] = r
    return results


def _healthy_alarm(records: list[RunRecord], cal: Calibration
                   ) -> dict[str, dict[str, float]]:
    """False alarms of each method on the healthy runs (first period skipped)."""
    healthy_alarm = {}
    for mth in METHODS:
        alarms = [_alarm_series(mth, rec, cal)[1:] for rec in records]
        n = sum(len(a) for a in alarms)
        healthy_alarm[mth] = {
            "period_rate": float(sum(int(a.sum()) for a in alarms) / n) if n else math.nan,
            "run_rate": float(np.mean([a.any() for a in alarms])) if alarms else math.nan,
            "periods": float(n)}
    return healthy_alarm


def _example(ex: RunScore, rec: RunRecord, cal: Calibration, seed: int) -> dict[str, Any]:
    """The fused estimate and predictions of one run, for the campaign figure."""
    fr = FusedPredictor(cal, seed=seed + ex.index).run(rec.t_s, rec.table)
    return {"index": ex.index, "t_s": rec.t_s.tolist(),
            "b_true_um": (rec.truth["backlash_m"] * 1e6).tolist(),
            "b_fused_um": fr.b_um.tolist(), "ci": rec.table["ci"].tolist(),
            "ci_harmonic": rec.table["ci_harmonic"].tolist(),
            "t_failure_s": ex.t_failure_s, "t_warning_s": fr.t_warning_s,
            "pred_t": [p.t_pred_s for p in fr.predictions],
            "pred_rul": [p.rul_s for p in fr.predictions],
            "pred_lo": [p.band()[0] - p.t_pred_s for p in fr.predictions],
            "pred_hi": [p.band()[1] - p.t_pred_s for p in fr.predictions]}


def _summary(scores: list[RunScore], healthy: dict[str, dict[str, float]]
             ) -> dict[str, dict[str, float]]:
    """Per method: medians and shares over the scored runs, and the false alarms."""
    out: dict[str, dict[str, float]] = {}
    for mth in METHODS:
        rs = [s.per_method[mth] for s in scores if not s.per_method[mth].get("censored")]
        if not rs:
            continue
        out[mth] = {
            **summarise_scores(rs),
            "false_alarm_period_rate": healthy[mth]["period_rate"],
            "false_alarm_run_rate": healthy[mth]["run_rate"],
        }
    return out


# --- figure and text -----------------------------------------------------------------------------

def campaign_figure(res: CampaignResult, out_dir: str | Path) -> list[Path]:
    """Prognostic horizon and warning time per run, and the example's fused estimate."""
    from matplotlib.figure import Figure  # matplotlib only when figures are asked for
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(15, 3.8))
    ax = fig.subplots(1, 3)
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
    return [p]


def campaign_markdown(res: CampaignResult) -> str:
    """The generated campaign section of docs/hums.md."""
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
            *LAMBDA_ROWS,
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
    """The campaign as JSON (non-finite numbers as null)."""
    return json_safe({"summary": res.summary, "healthy_alarm": res.healthy_alarm,
                "runs": [{"index": s.index, "params": s.params, "t_failure_s": s.t_failure_s,
                          "methods": s.per_method} for s in res.scores],
                "calibration": {k: v for k, v in res.cal.to_json().items()
                                if k != "healthy_fused_um"},
                "elapsed_s": res.elapsed_s, "machine": res.machine})
