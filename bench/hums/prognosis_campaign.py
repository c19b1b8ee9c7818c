"""The 50-actuator usage campaign: calibration on calibration actuators, the
prognosis of every judged actuator day by day, and its scores with progpy's metrics.

Seeds (every threshold and prior comes from actuators distinct from the judged ones):

- calibration sweep: one actuator (seed `CAL_SWEEP_SEED`, friction x1.0), ground tests at
  known worn volumes, noise-free and with noise seeds `CAL_SWEEP_SEED * 1000 + j`;
- calibration actuators (`CAL_SEED + c`): run to failure; the prior of the wear
  coefficient (per unit of exposure, and per day) and the population's exposure rate;
- calibration healthy actuators (`CAL_HEALTHY_SEED + h`, no wear): the friction scale's
  spread and the warning level;
- judged actuators (`seed + k`) and judged healthy actuators (`HEALTHY_SEED + h`).

Methods scored on the judged actuators (`bench.hums.prognosis.WearPrognoser`):
``usage+health`` (the particle filter with the usage's exposure and the ground tests),
``usage`` (the prior moved by the usage alone, never weighed by a ground test) and
``health`` (time as the exposure, the ground tests: what `bench hums prognose --trends`
does with trends from another rig).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError, machine_description
from bench.core.jsonsafe import json_safe
from bench.hums import usage_campaign as U
from bench.hums.metrics import LAMBDA_ROWS, score_run, summarise_scores
from bench.hums.prognosis import (
    PrognosisCalibration,
    WearPrognoser,
    index_wear,
)
from bench.hums.rul import FAILURE, Prediction
from plant_rt.params import PlantParams

CAL_SWEEP_SEED = 9990
CAL_SEED = 9000
CAL_HEALTHY_SEED = 9500
HEALTHY_SEED = 5000
OUTPUTS = ["friction_current_a", "lost_motion_um", "ci_harmonic"]
METHODS = ("usage+health", "usage", "health")
SWEEP_POINTS = 12
SWEEP_NOISY = 3
SCORE_SAMPLES = 250


@dataclass
class UsageCampaignResult:
    """Per-actuator scores, false alarms, summary and the calibration used."""
    runs: list[dict[str, Any]]
    summary: dict[str, dict[str, float]]
    false_alarms: dict[str, float]
    cal: PrognosisCalibration
    elapsed_s: float
    sim_s: float
    args: dict[str, Any]
    machine: str
    extra: dict[str, Any] = field(default_factory=dict)


def sweep_jobs(base: PlantParams, kp: float, points: int = SWEEP_POINTS,
               noisy: int = SWEEP_NOISY) -> tuple[list[dict[str, Any]], float]:
    """Calibration ground tests: volumes from new to past failure (backlash 130 um)."""
    from plant_rt.wear import volume_for_backlash
    p, _ = U.actuator_params(base, CAL_SWEEP_SEED)
    p = p.with_dict({"effects.friction_scale": 1.0})
    vmax = volume_for_backlash(130e-6, p)
    vols = vmax * np.linspace(0.0, 1.0, points) ** 1.5
    jobs = []
    for j, v in enumerate(vols):
        jobs.append({"params": p.to_json(), "kp": kp, "volume_m3": float(v),
                     "noise_seed": None})
        jobs += [{"params": p.to_json(), "kp": kp, "volume_m3": float(v),
                  "noise_seed": CAL_SWEEP_SEED * 1000 + 10 * j + r} for r in range(noisy)]
    return jobs, vmax


def calibrate(sweep: list[dict[str, Any]], cal_runs: list[dict[str, Any]],
              cal_healthy: list[dict[str, Any]]) -> PrognosisCalibration:
    """Observation model from the sweep, priors from the calibration actuators, friction
    spread and warning level from the calibration healthy actuators."""
    # long: the three calibration steps in order, each a few lines
    vols = sorted({r["volume_m3"] for r in sweep})
    clean = {r["volume_m3"]: r for r in sweep if r["noise_seed"] is None}
    ci_true = np.array([clean[v]["ci"] for v in vols])
    below = np.flatnonzero(ci_true < FAILURE)
    if not len(below) or below[0] == 0:
        raise BenchError("the calibration sweep does not cross Ci = 0.56")
    k = below[0]
    v_fail = vols[k - 1] + (ci_true[k - 1] - FAILURE) / (ci_true[k - 1] - ci_true[k]) * (
        vols[k] - vols[k - 1])
    w = [v / v_fail for v in vols]
    curves: dict[str, list[float]] = {}
    sigma: dict[str, float] = {}
    for name in OUTPUTS:
        means, resid = [], []
        for v in vols:
            vals = np.array([r[name] for r in sweep if r["volume_m3"] == v
                             and r["noise_seed"] is not None])
            means.append(float(np.mean(vals)))
            resid += list(vals - vals.mean())
        curves[name] = means
        dof = len(resid) - len(vols)
        sigma[name] = float(math.sqrt(np.sum(np.square(resid)) / max(dof, 1)))
    e_fail, t_fail, rates = [], [], []
    for r in cal_runs:
        if not math.isfinite(r["t_failure"]):
            continue
        e = np.array([d.get("exposure_n_rev", 0.0) for d in r["days"]])
        cum = np.concatenate([[0.0], np.cumsum(e)])
        tf = r["t_failure"]
        i = int(math.floor(tf))
        e_fail.append(cum[min(i, len(cum) - 1)] + (tf - i) * (e[i] if i < len(e) else 0.0))
        t_fail.append(tf)
        rates.append(float(np.mean(e[e > 0])))
    if len(e_fail) < 2:
        raise BenchError("fewer than two calibration actuators failed: no prior")
    lnk, lnkt = -np.log(e_fail), -np.log(t_fail)
    cal = PrognosisCalibration(
        w_grid=w, curves=curves, sigma=sigma,
        lnk_mean=float(np.mean(lnk)), lnk_std=max(float(np.std(lnk, ddof=1)), 0.05),
        lnk_time_mean=float(np.mean(lnkt)),
        lnk_time_std=max(float(np.std(lnkt, ddof=1)), 0.05),
        exposure_rate_mean=float(np.mean(rates)), v_fail_m3=float(v_fail))
    # friction of a new actuator: spread of the calibration healthy actuators' friction
    # current around the curve's new value, less the ground test's own noise
    f0 = curves["friction_current_a"][0]
    ratios = [np.log(np.mean([d["friction_current_a"] for d in r["days"]]) / f0)
              for r in cal_healthy]
    n_days = np.mean([len(r["days"]) for r in cal_healthy]) if cal_healthy else 1.0
    var = float(np.var(ratios, ddof=1)) - (sigma["friction_current_a"] / f0) ** 2 / n_days \
        if len(ratios) > 1 else 0.0
    cal.lfs_std = float(math.sqrt(max(var, 0.02 ** 2)))
    # warning: the index-only wear of a healthy ground test above mean + 5 sd
    wi = np.array([index_wear(cal, {o: d[o] for o in OUTPUTS}) for r in cal_healthy
                   for d in r["days"]])
    wi = wi[np.isfinite(wi)]
    cal.warn_w = float(np.mean(wi) + 5.0 * np.std(wi, ddof=1)) if len(wi) > 1 else 0.1
    cal.seeds = {"sweep": [CAL_SWEEP_SEED], "actuators": [int(r["seed"]) for r in cal_runs],
                 "healthy": [int(r["seed"]) for r in cal_healthy]}
    cal.notes = {"healthy_ground_tests": int(len(wi)),
                 "failed_calibration_actuators": len(e_fail),
                 "calibration_life_days": [float(x) for x in t_fail]}
    return cal


def prognose_run(job: tuple[dict[str, Any], dict[str, Any], int]) -> dict[str, Any]:
    """Worker: the three methods on one judged actuator, scored with progpy."""
    run, cal_json, seed = job
    cal = PrognosisCalibration.from_json(cal_json)
    t_f = run["t_failure"]
    out: dict[str, Any] = {"seed": run["seed"], "t_failure": t_f,
                           "severity": run["severity"], "days": len(run["days"])}
    rows = run["days"]
    wi = [index_wear(cal, {o: d[o] for o in OUTPUTS}) for d in rows]
    warn = [d["day"] for d, x in zip(rows, wi, strict=True) if x > cal.warn_w]
    t_warn = float(warn[0]) if warn else math.nan
    out["miner_life_consumed"] = float(sum(d.get("life_consumed", 0.0) for d in rows)
                                       * run.get("acceleration", U.ACCELERATION))
    if not math.isfinite(t_f):
        out["censored"] = True
        return out
    for m in METHODS:
        pr = WearPrognoser(cal, OUTPUTS, n_particles=1000, seed=seed,
                           time_only=(m == "health"))
        preds: list[Prediction] = []
        band = []
        prev_e = 0.0
        for d in rows:
            t = d["day"]
            if t >= t_f:
                break
            obs = None if m == "usage" else {o: d[o] for o in OUTPUTS}
            est = pr.update(t, prev_e, obs)
            prev_e = d.get("exposure_n_rev", 0.0)
            toe = pr.toe_samples()
            sub = np.random.default_rng(seed + int(t)).choice(toe, SCORE_SAMPLES)
            preds.append(Prediction(t, sub))
            band.append([t, est.rul_pct["5"], est.rul_pct["50"], est.rul_pct["95"]])
        sc = score_run(preds, t_warn, t_f, cadence=1.0)
        sc["band"] = band
        sc["first_rul"] = band[0][1:] if band else []
        out[m] = sc
    return out


def run_usage_campaign(n: int = 50, n_cal: int = 8, n_healthy: int = 5,
                       n_cal_healthy: int = 4, seed: int = 2024,
                       params: PlantParams | None = None, workers: int | None = None,
                       progress: bool = True, max_days: int = U.MAX_DAYS,
                       healthy_days: int = 40, acceleration: float = U.ACCELERATION,
                       sweep_points: int = SWEEP_POINTS, sweep_noisy: int = SWEEP_NOISY,
                       cal_healthy_days: int = 15, kp: float | None = None
                       ) -> UsageCampaignResult:
    """Simulate, calibrate, prognose and score (module docstring)."""
    from bench.hums import monitor as M
    from bench.runtime.workers import run_all
    if n < 1 or n_cal < 2:
        raise BenchError("the usage campaign needs >= 1 judged and >= 2 calibration "
                         "actuators")
    if seed + n > HEALTHY_SEED or seed < 1:
        raise BenchError(f"--seed must be in 1..{HEALTHY_SEED - n} (judged actuators are "
                         "seed..seed+n-1, apart from the calibration seeds)")
    t0 = time.perf_counter()
    base = params or PlantParams()
    kp = kp or M.fitted(base)[0].gain_rad_s_per_m
    sweeps, _ = sweep_jobs(base, kp, sweep_points, max(2, sweep_noisy))
    jobs: list[tuple[str, dict[str, Any]]] = [("sweep", j) for j in sweeps]

    def days_job(s: int, healthy: bool, nd: int) -> tuple[str, dict[str, Any]]:
        p, sev = U.actuator_params(base, s, healthy)
        return ("days", {"params": p.to_json(), "kp": kp, "seed": s, "severity": sev,
                         "healthy": healthy, "max_days": nd,
                         "acceleration": acceleration})
    groups = {"cal": [days_job(CAL_SEED + c, False, max_days) for c in range(n_cal)],
              "cal_healthy": [days_job(CAL_HEALTHY_SEED + h, True, cal_healthy_days)
                              for h in range(n_cal_healthy)],
              "judged": [days_job(seed + k, False, max_days) for k in range(n)],
              "healthy": [days_job(HEALTHY_SEED + h, True, healthy_days)
                          for h in range(n_healthy)]}
    for g in groups.values():
        jobs += g
    res = U.run_jobs(jobs, workers, progress)
    sim_s = time.perf_counter() - t0
    k = len(sweeps)
    got: dict[str, list[dict[str, Any]]] = {}
    for name, g in groups.items():
        got[name] = res[k:k + len(g)]
        k += len(g)
    cal = calibrate(res[:len(sweeps)], got["cal"], got["cal_healthy"])
    scored = run_all(prognose_run, [(r, cal.to_json(), 7 + i)
                                    for i, r in enumerate(got["judged"])],
                     workers, progress, desc="prognosis", unit="actuator")
    fa = [index_wear(cal, {o: d[o] for o in OUTPUTS}) > cal.warn_w
          for r in got["healthy"] for d in r["days"]]
    false_alarms = {"ground_tests": float(len(fa)), "alarms": float(sum(fa)),
                    "rate": float(np.mean(fa)) if fa else math.nan}
    out = UsageCampaignResult(scored, summarise(scored), false_alarms, cal,
                              time.perf_counter() - t0, sim_s,
                              {"n": n, "n_cal": n_cal, "n_healthy": n_healthy,
                               "n_cal_healthy": n_cal_healthy, "seed": seed,
                               "max_days": max_days, "healthy_days": healthy_days,
                               "acceleration": acceleration},
                              machine_description())
    out.extra["sweep"] = res[:len(sweeps)]
    out.extra["judged"] = got["judged"]
    return out


def summarise(runs: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Per method: shares and medians over the failed (uncensored) judged actuators."""
    ok = [r for r in runs if not r.get("censored")]
    out: dict[str, dict[str, float]] = {}
    for m in METHODS:
        rs = [r[m] for r in ok]
        if not rs:
            continue

        out[m] = summarise_scores(rs)
    out["all"] = {"actuators": float(len(runs)), "failed": float(len(ok)),
                  "life_days_median": float(np.median([r["t_failure"] for r in ok]))
                  if ok else math.nan,
                  "life_days_min": float(min(r["t_failure"] for r in ok)) if ok else math.nan,
                  "life_days_max": float(max(r["t_failure"] for r in ok)) if ok else math.nan,
                  "miner_at_failure_median": float(np.median(
                      [r["miner_life_consumed"] for r in ok])) if ok else math.nan}
    return out


def write_trends(res: UsageCampaignResult, path: str | Path) -> Path:
    """The judged actuators' daily ground-test indexes and flight exposures as a trends
    CSV (`bench.hums.prognosis_trends`): what `bench hums prognose --trends` reads."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time", "actuator", "index", "value"])
        for r in res.extra.get("judged", []):
            prev = None
            for d in r["days"]:
                a = f"A{r['seed']}"
                if prev is not None:
                    w.writerow([d["day"], a, "exposure", prev])
                for name in OUTPUTS:
                    w.writerow([d["day"], a, name, d[name]])
                prev = d.get("exposure_n_rev")
    return p


def figure(res: UsageCampaignResult, out_dir: str | Path) -> list[Path]:
    """Prognostic horizon per actuator and method, and one actuator's RUL bands."""
    from matplotlib.figure import Figure  # matplotlib only when figures are asked for
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    runs = [r for r in res.runs if not r.get("censored")]
    fig = Figure(figsize=(13, 4))
    ax = fig.subplots(1, 2)
    for k, m in enumerate(METHODS):
        ph = [r[m]["ph_life_frac"] for r in runs]
        ax[0].bar(np.arange(len(ph)) + (k - 1) * 0.27, ph, width=0.27, label=m)
    ax[0].axhline(0.5, color="k", ls="--", lw=1)
    ax[0].set(title="prognostic horizon / life (alpha 0.2, progpy)", xlabel="actuator",
              ylabel="PH / life")
    ax[0].legend(fontsize=7)
    if runs:
        ex = sorted(runs, key=lambda r: r["t_failure"])[len(runs) // 2]   # median life
        t_f = ex["t_failure"]
        tt = np.linspace(0, t_f, 50)
        ax[1].plot(tt, t_f - tt, "k-", label="true RUL")
        ax[1].fill_between(tt, 0.8 * (t_f - tt), 1.2 * (t_f - tt), color="0.85",
                           label="+-20 %")
        for m, c in (("usage+health", "C0"), ("usage", "C1")):
            b = np.array(ex[m]["band"])
            ax[1].plot(b[:, 0], b[:, 2], c + "o-", ms=3, label=f"{m}: median")
            ax[1].fill_between(b[:, 0], b[:, 1], b[:, 3], color=c, alpha=0.2,
                               label=f"{m}: 5-95 %")
        ax[1].set(title=f"actuator {ex['seed']} (life {t_f:.1f} days)", xlabel="day",
                  ylabel="RUL (days)")
        ax[1].legend(fontsize=7)
    fig.tight_layout()
    p = out / "usage_campaign.png"
    fig.savefig(p, dpi=90)
    return [p]


# --- text and JSON ----------------------------------------------------------------------------

_ROWS = [("ph_before_half_life", "correct RUL band (alpha 0.2) before 50 % of life "
          "(prognostic horizon >= 50 % of life)", "{:.0%}"),
         ("ph_life_frac_median", "prognostic horizon / life, median (progpy)", "{:.0%}"),
         ("stable_ph_life_frac_median", "horizon from which every prediction stays within "
          "alpha / life, median", "{:.0%}"),
         *LAMBDA_ROWS,
         ("warned_runs", "actuators warned before failure", "{:.0%}"),
         ("warning_life_frac_median", "warning time / life, median", "{:.0%}")]


def markdown(res: UsageCampaignResult) -> str:
    """The generated usage-campaign section of docs/hums.md."""
    a, s, cal = res.args, res.summary, res.cal
    al = s.get("all", {})
    lines = [f"Generated by `bench hums campaign --usage --runs {a['n']} --seed {a['seed']}` "
             f"on {res.machine}; wall time {res.elapsed_s:.0f} s ({res.sim_s:.0f} s of "
             "simulation on the worker pool). Judged actuators: seeds "
             f"{a['seed']}-{a['seed'] + a['n'] - 1}; calibration actuators "
             f"{cal.seeds.get('actuators')}, calibration healthy {cal.seeds.get('healthy')}, "
             f"sweep {cal.seeds.get('sweep')}; judged healthy {HEALTHY_SEED}-"
             f"{HEALTHY_SEED + a['n_healthy'] - 1}. Metrics from `progpy.metrics` on each "
             "actuator's daily predictions (250 ToE samples each), alpha = 0.2, beta = 0.5.",
             "", f"Judged actuators: {al.get('actuators', 0):.0f}, failed (Ci of the "
             f"noise-free ground test < 0.56) within {a['max_days']} days: "
             f"{al.get('failed', 0):.0f}; life {al.get('life_days_min', math.nan):.1f}-"
             f"{al.get('life_days_max', math.nan):.1f} days (median "
             f"{al.get('life_days_median', math.nan):.1f}); time compression x"
             f"{a['acceleration']:g} on the wear of each simulated 30 s flight.", "",
             "| metric | usage + health | usage only | health only (time) |",
             "|---|---|---|---|"]
    for key, label, f in _ROWS:
        cells = []
        for m in METHODS:
            v = s.get(m, {}).get(key, math.nan)
            cells.append("-" if not math.isfinite(v) else f.format(v))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    fa = res.false_alarms
    lines += ["", f"False alarms: {fa['alarms']:.0f} of {fa['ground_tests']:.0f} ground tests "
              f"of {a['n_healthy']} healthy actuators ({fa['rate']:.2%}); warning level "
              f"w > {cal.warn_w:.3f} (index-only wear of one ground test; mean + 5 sd of "
              f"{cal.notes.get('healthy_ground_tests', 0)} calibration healthy ground tests).",
              "", "Calibration: prior ln k = "
              f"{cal.lnk_mean:.2f} +- {cal.lnk_std:.2f} (w per N rev of exposure), time-only "
              f"{cal.lnk_time_mean:.2f} +- {cal.lnk_time_std:.2f} (w per day), from "
              f"{cal.notes.get('failed_calibration_actuators')} calibration actuators "
              "(lives " + ", ".join(f"{x:.1f}" for x in
                                    cal.notes.get("calibration_life_days", [])) +
              " days); index noise " + ", ".join(f"{k} {v:.4g}" for k, v in cal.sigma.items())
              + f"; new friction spread (ln) {cal.lfs_std:.3f}; w = 1 at a worn volume of "
              f"{cal.v_fail_m3:.3e} m^3. Miner (ISO 3408-5 L10) life consumed at the wear-out "
              f"failure, median {al.get('miner_at_failure_median', math.nan):.3g} "
              "(compression included)."]
    return "\n".join(lines) + "\n"


def to_json(res: UsageCampaignResult) -> dict[str, Any]:
    """The campaign as JSON (non-finite numbers as null)."""
    return json_safe({"summary": res.summary, "false_alarms": res.false_alarms,
                "runs": res.runs, "calibration": res.cal.to_json(), "args": res.args,
                "elapsed_s": res.elapsed_s, "sim_s": res.sim_s, "machine": res.machine})
