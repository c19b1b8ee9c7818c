"""The trend's own prognosis (`bench hums prognose` without a calibration) scored as of
each test day, beside its peers on the same tests.

1. **Synthetic endurance trends** (`bench.hums.trend_synth`, held-out seeds 1000 +,
   apart from the development seeds 100-139 and the tests' 2-11): per shape, the share
   of trends warned at least 14 days before failure, warnings before the onset, the
   share of test days after the first warning with the truth inside the 90 % band
   (and of trends where that is at least half), narrow bands without a note; the
   z-score peer's (3 sd of the healthy tests) and the exponential peer's alarms.
2. **The bench's own campaign as a foreign file**: the judged actuators of `bench hums
   campaign --usage` (its `--trends-out`, `--json` and `--calibration-out`), each index
   renamed, days as dates, no exposure rows and no calibration, failure threshold the
   index's value at the calibration's w = 1 (the limit a rig's engineer would know from
   the lab's teardown); progpy's prognostic horizon and alpha-lambda (alpha 0.2,
   beta 0.5) on 250 samples per day, as the campaign scores its calibrated paths, whose
   numbers are beside them.

    python benchmarks/eval_trend_prognosis.py --seeds 20 \\
        --campaign DIR   # DIR holds trends.csv, campaign.json, cal.json
    python benchmarks/eval_trend_prognosis.py ... --doc docs/trend-results.md
    python benchmarks/eval_trend_prognosis.py --final-check 20 --doc docs/trend-results.md

`--doc` replaces the generated section ``trend-prognosis`` of docs/trend-results.md;
with `--final-check N` (N trends of each law of `bench.hums.trend_check`, the final
check), its section ``trend-final-check``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections import defaultdict
from datetime import date, timedelta
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEED0 = 1000
DEV_SEEDS = "100-139"      # synthetic seeds the model was developed on
HELD_FROM = 2049           # campaign actuators from this seed on: never looked at in development
CAMPAIGN_INDEXES = {"lost_motion_um": ("backlash_um", "um", False),
                    "friction_current_a": ("motor_current_rms", "A", False),
                    "ci_harmonic": ("harmonic_ci", "", True)}


def score_synthetic(st: Any, healthy: str = "5") -> dict[str, Any]:
    """One synthetic trend as of each test day: warning, coverage, notes, peers."""
    from bench.hums.trend_io import Trend
    from bench.hums.trend_prognosis import Settings, prognose
    tr = Trend(st.name, "rms_current", st.unit, st.t, st.y, np.arange(len(st.t)))
    r = prognose(tr, Settings(healthy=healthy, failure=repr(float(st.failure_level))))
    c, ev, tf = r.cols, r.events, st.t_failure
    warn = np.flatnonzero(c["warning"] > 0)
    tw = float(st.t[warn[0]]) if len(warn) else math.nan
    after = [k for k in range(len(st.t)) if len(warn) and tw <= st.t[k] < tf]
    inside = [c["rul_p5"][k] <= tf - st.t[k] <= c["rul_p95"][k] for k in after]
    narrow = [k for k in np.flatnonzero(np.isfinite(c["rul_p5"]))
              if c["rul_p95"][k] - c["rul_p5"][k] < 0.25 * r.ref.dt and not r.notes_at.get(k)]
    return {"shape": st.shape, "life": tf, "lead": tf - tw, "false": bool(len(warn))
            and tw < st.onset, "cover": float(np.mean(inside)) if inside else math.nan,
            "days_after": len(after), "narrow_silent": len(narrow),
            "z_lead": tf - ev.get("z_alarm_t", math.nan),
            "z_false": ev.get("z_alarm_t", math.inf) < st.onset,
            "exp_lead": tf - ev.get("exp_alarm_t", math.nan),
            "exp_false": ev.get("exp_alarm_t", math.inf) < st.onset}


def synthetic(seeds: int, final: bool = False) -> dict[str, dict[str, float]]:
    """Per shape of `bench.hums.trend_synth` (held-out seeds from SEED0), or with `final`
    of the final check's `bench.hums.trend_check` (its own fixed seeds)."""
    if final:
        from bench.hums.trend_check import SHAPES, final_trend

        def draw(shape: str, i: int) -> Any:
            return final_trend(shape, i)
    else:
        from bench.hums.trend_synth import SHAPES, endurance_trend

        def draw(shape: str, i: int) -> Any:
            return endurance_trend(shape, SEED0 + i)
    out = {}
    for shape in SHAPES:
        rows = [score_synthetic(draw(shape, i)) for i in range(seeds)]
        failing = [r for r in rows if math.isfinite(r["life"])]

        def share(key: str, rs: list[dict[str, Any]] = failing) -> float:
            return float(np.mean([bool(r[key]) for r in rs])) if rs else math.nan

        def med(key: str, rs: list[dict[str, Any]] = failing) -> float:
            v = np.array([r[key] for r in rs], dtype=float)
            return float(np.nanmedian(v)) if np.isfinite(v).any() else math.nan
        cov = [r["cover"] for r in failing if math.isfinite(r["cover"])]
        out[shape] = {
            "trends": float(len(rows)),
            "warned_14": float(np.mean([r["lead"] >= 14 for r in failing])) if failing
            else math.nan,
            "false": float(np.mean([r["false"] for r in rows])),
            "cover_mean": float(np.mean(cov)) if cov else math.nan,
            "cover_half": float(np.mean([x >= 0.5 for x in cov])) if cov else math.nan,
            "narrow_silent": float(sum(r["narrow_silent"] for r in rows)),
            "lead_median": med("lead"), "z_lead_median": med("z_lead"),
            "z_14": float(np.mean([r["z_lead"] >= 14 for r in failing])) if failing
            else math.nan,
            "z_false": float(np.mean([r["z_false"] for r in rows])),
            "exp_lead_median": med("exp_lead"),
            "exp_14": float(np.mean([r["exp_lead"] >= 14 for r in failing])) if failing
            else math.nan,
            "exp_false": float(np.mean([r["exp_false"] for r in rows])),
        }
    return out


def _campaign_rows(d: Path) -> tuple[dict[str, dict[str, list[tuple[float, float]]]],
                                     dict[str, float], dict[str, Any], dict[str, Any]]:
    camp = json.loads((d / "campaign.json").read_text())
    cal = json.loads((d / "cal.json").read_text())
    truth = {f"A{r['seed']}": r["t_failure"] for r in camp["runs"] if not r.get("censored")}
    rows: dict[str, dict[str, list[tuple[float, float]]]] = defaultdict(lambda: defaultdict(list))
    with (d / "trends.csv").open() as fh:
        for r in csv.DictReader(fh):
            rows[r["actuator"]][r["index"]].append((float(r["time"]), float(r["value"])))
    return rows, truth, camp, cal


def foreign_file(rows: dict[str, Any], index: str, path: Path) -> Path:
    """The campaign's trends of one index as a rig would give them: renamed, dates, its
    unit, no exposure rows."""
    name, unit, _ = CAMPAIGN_INDEXES[index]
    start = date(2024, 1, 1)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["date", "actuator", "index", "value", "unit"])
        for a, d in rows.items():
            for t, v in d[index]:
                w.writerow([(start + timedelta(days=t)).isoformat(), f"rig-{a[1:]}", name,
                            repr(v), unit])
    return path


def score_campaign(d: Path, index: str, healthy: str, work: Path) -> dict[str, Any]:
    """The foreign file of one index through the CLI (end to end) and scored as of each
    day with progpy's metrics."""
    import subprocess

    from bench.hums.metrics import score_run
    from bench.hums.rul import Prediction
    from bench.hums.trend_io import read_table
    from bench.hums.trend_prognosis import Settings, prognose
    rows, truth, _, cal = _campaign_rows(d)
    limit = float(np.interp(1.0, cal["w_grid"], cal["curves"][index]))
    name, unit, falls = CAMPAIGN_INDEXES[index]
    f = foreign_file(rows, index, work / f"{name}.csv")
    out = work / f"{name}.json"
    argv = [sys.executable, "-m", "bench", "hums", "prognose", "--trends", str(f),
            "--healthy-tests", healthy, "--failure", repr(limit), "--json", str(out)]
    t0 = time.perf_counter()
    import os
    subprocess.run(argv + (["--decreasing"] if falls else []), check=True, cwd=ROOT,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env={**os.environ, "PYTHONPATH": str(ROOT)})
    cli_s = time.perf_counter() - t0
    cli = json.loads(out.read_text())
    s = Settings(healthy=healthy, failure=repr(limit), decreasing=falls, keep_samples=250)
    scores = []
    for tr in read_table(f).trends:
        tf = truth.get("A" + tr.actuator.split("-", 1)[1])
        if tf is None:
            continue
        r = prognose(tr, s)
        last = cli[tr.actuator][-1]
        assert last["rul_p50"] == (None if not math.isfinite(r.cols["rul_p50"][-1])
                                   else float(r.cols["rul_p50"][-1])), tr.actuator
        preds = [Prediction(float(tr.t[k]), float(tr.t[k]) + np.minimum(v, 1e6))
                 for k, v in sorted(r.samples.items()) if tr.t[k] < tf]
        warn = np.flatnonzero(r.cols["warning"] > 0)
        sc = score_run(preds, float(tr.t[warn[0]]) if len(warn) else math.nan, tf,
                       cadence=1.0)
        sc["seed"] = int(tr.actuator.split("-", 1)[1])
        # the side of the truth the median lies on where alpha-lambda at 70 % is missed
        # (the prediction score_run scores there)
        at = [p for p in preds if 0.7 * tf - 1e-9 <= p.t_pred_s <= 0.7 * tf + 1.0]
        sc["side_0.7"] = ("" if sc["alpha_lambda_0.7"] or not at else
                          "early" if np.median(at[0].toe_samples) < tf else "late")
        scores.append(sc)
    summ = _summary(scores)
    lim = [index_limits(dict(rows[a][index]), tf, limit, int(healthy))
           for a, tf in truth.items() if a in rows]
    summ.update(index=name, limit=limit, cli_s=cli_s,
                held_out=_summary([x for x in scores if x["seed"] >= HELD_FROM]),
                **_limits_summary(lim))
    return summ


def index_limits(trend: dict[float, float], t_f: float, limit: float, healthy: int
                 ) -> dict[str, float]:
    """What the trend itself allows of one actuator's index, in hindsight: the level
    u (0 the mean of the first `healthy` tests, 1 the threshold) and least-squares lines
    through the tests from 45 to 70 % of life and from 70 % on. `rate_ratio`: the rate
    after 70 % of life over the rate before it (1: a straight line); `u_fail`: the later
    line at the failure (1: the failure is the threshold's); `line_ok`: the earlier line
    extrapolated from the test at 70 % of life to u = 1 lies within +-20 % of the true
    RUL (the window needs the true life: a bound on extrapolating the recent rate, not a
    method); `ratio_fail`, `value_fail`: the index at failure over the healthy level and
    over the threshold."""
    t, y = (np.array(v, dtype=float) for v in zip(*sorted(trend.items()), strict=True))
    h0 = float(np.mean(y[:healthy]))
    u = (y - h0) / (limit - h0)
    k = int(np.searchsorted(t, 0.7 * t_f - 1e-9))
    before, after = (t >= 0.45 * t_f) & (t <= t[k]), t >= t[k]
    if before.sum() < 3 or after.sum() < 3:
        return {}
    p1, p2 = np.polyfit(t[before], u[before], 1), np.polyfit(t[after], u[after], 1)
    u_fail = float(np.polyval(p2, t_f))
    rul = (1.0 - float(np.polyval(p1, t[k]))) / p1[0] if p1[0] > 0 else math.inf
    y_fail = h0 + u_fail * (limit - h0)
    return {"rate_ratio": float(p2[0] / p1[0]), "u_fail": u_fail,
            "line_ok": float(abs(rul - (t_f - t[k])) <= 0.2 * (t_f - t[k])),
            "ratio_fail": y_fail / h0, "value_fail": y_fail / limit}


def _limits_summary(lim: list[dict[str, float]]) -> dict[str, Any]:
    """`index_limits` over the actuators: the medians and ranges of the table, the
    spread (sd over mean) of the index at failure about the threshold and about a
    multiple of the healthy level."""
    def col(key: str) -> np.ndarray:
        return np.array([x[key] for x in lim if key in x])
    r, uf = col("rate_ratio"), col("u_fail")
    if not len(r):
        return {}
    return {"rate_ratio_median": float(np.median(r)), "rate_ratio_range": (
        float(r.min()), float(r.max())), "u_fail_range": (float(uf.min()), float(uf.max())),
        "line_ok": float(np.mean(col("line_ok"))),
        "cv_threshold": float(np.std(col("value_fail")) / np.mean(col("value_fail"))),
        "cv_healthy": float(np.std(col("ratio_fail")) / np.mean(col("ratio_fail")))}


def _summary(scores: list[dict[str, Any]]) -> dict[str, Any]:
    summ: dict[str, Any] = {"actuators": len(scores), "ph_before_half_life": float(np.mean(
        [x["ph_life_frac"] >= 0.5 for x in scores]))}
    for lam in ("0.5", "0.7", "0.9"):
        summ[f"alpha_lambda_{lam}"] = float(np.mean([bool(x[f"alpha_lambda_{lam}"])
                                                     for x in scores]))
        ra = np.array([x[f"ra_{lam}"] for x in scores], dtype=float)
        summ[f"ra_{lam}_median"] = float(np.nanmedian(ra)) if np.isfinite(ra).any() else math.nan
    summ["missed_early_0.7"] = float(sum(x.get("side_0.7") == "early" for x in scores))
    summ["missed_late_0.7"] = float(sum(x.get("side_0.7") == "late" for x in scores))
    summ["warned"] = float(np.mean([math.isfinite(x["t_warning_s"]) for x in scores]))
    summ["warning_life_frac_median"] = float(np.nanmedian(
        [x["warning_life_frac"] for x in scores]))
    return summ


def _pct(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v:.0%}"


def _shape_table(syn: dict[str, Any], first: str = "shape") -> list[str]:
    """The per-shape table (header, rule, one row per shape of `synthetic`); `first` names
    the first column."""
    return [f"| {first} | warned >= 14 d before | warnings before the onset | truth in the "
            "90 % band, days after the warning | trends with it on >= half of them | "
            "narrow bands without a note | z-score peer: >= 14 d / before the onset | "
            "exponential peer: >= 14 d / before the onset |",
            "|---|---|---|---|---|---|---|---|"] + [f"| {shape} | {_pct(s['warned_14'])} | {_pct(s['false'])} | "
            f"{_pct(s['cover_mean'])} | {_pct(s['cover_half'])} | "
            f"{s['narrow_silent']:.0f} | {_pct(s['z_14'])} / {_pct(s['z_false'])} | "
            f"{_pct(s['exp_14'])} / {_pct(s['exp_false'])} |" for shape, s in syn.items()]


def final_markdown(syn: dict[str, Any], n: int, machine: str, wall: float) -> str:
    """The final check's table (`--final-check N`)."""
    from bench.hums.trend_check import FINAL_SEED
    return "\n".join([
        f"Generated by `python benchmarks/eval_trend_prognosis.py --final-check {n}` on "
        f"{machine}; {wall:.0f} s. Laws the model was not developed on "
        f"(`bench.hums.trend_check`, seeds {FINAL_SEED} + 100 x shape + 0-{n - 1}, fixed "
        "before the run); failure at twice the healthy level, stated with `--failure`; "
        "`--healthy-tests 5`; every estimate from the tests up to its day:", "",
        *_shape_table(syn, "law")]) + "\n"


def markdown(syn: dict[str, Any], camp: list[dict[str, Any]] | None,
             calibrated: dict[str, Any] | None, args: Any, machine: str) -> str:
    # long: two tables and their headers
    lines = [f"Generated by `python benchmarks/eval_trend_prognosis.py --seeds {args.seeds}"
             + (" --campaign DIR" if camp else "") + f"` on {machine}. Every estimate uses "
             "only the tests up to its day (the command as of that day).", "",
             f"**Synthetic endurance trends** (`bench.hums.trend_synth`, seeds {SEED0}-"
             f"{SEED0 + args.seeds - 1} of each shape, held out from the development seeds "
             f"{DEV_SEEDS}; "
             "failure at twice the healthy level, stated with `--failure`; "
             "`--healthy-tests 5`):", "", *_shape_table(syn)]
    if camp:
        lines += ["", "**The bench's campaign as a foreign file** (`bench hums campaign "
                  "--usage` seed 2024, its 50 judged actuators; each index renamed, days "
                  "as dates, no exposure rows, no calibration; `--failure` the index at the "
                  "calibration's w = 1, `--healthy-tests 3`; progpy's metrics on 250 "
                  "samples a day, alpha 0.2, beta 0.5), beside the campaign's calibrated "
                  "paths on the same actuators. The trend's own model was developed on "
                  f"actuators 2024-{HELD_FROM - 1}; the held-out rows score the others "
                  "alone, the hindsight rows (every actuator, the true life known) say "
                  "what the trends themselves allow:", "",
                  "| metric | " + " | ".join(f"trend's own: {c['index']}" for c in camp)
                  + " | calibrated: usage + health | calibrated: health only |",
                  "|---|" + "---|" * (len(camp) + 2)]
        rows = [("ph_before_half_life", "correct RUL band before 50 % of life"),
                ("alpha_lambda_0.5", "alpha-lambda at 50 % of life"),
                ("alpha_lambda_0.7", "alpha-lambda at 70 % of life"),
                ("alpha_lambda_0.9", "alpha-lambda at 90 % of life"),
                ("ra_0.7_median", "relative accuracy at 70 %, median"),
                ("warning_life_frac_median", "warning time / life, median")]
        for key, label in rows:
            fmt = (lambda v: "-" if not math.isfinite(v) else f"{v:.2f}") if "ra_" in key \
                else _pct
            cal = [fmt((calibrated or {}).get(m, {}).get(key, math.nan))
                   for m in ("usage+health", "health")]
            lines.append(f"| {label} | " + " | ".join(fmt(c.get(key, math.nan)) for c in camp)
                         + " | " + " | ".join(cal) + " |")
        for key, label in rows[:4]:
            lines.append(f"| {label}, held-out actuators {HELD_FROM}-2073 only | "
                         + " | ".join(_pct(c["held_out"].get(key, math.nan)) for c in camp)
                         + " | - | - |")
        lines.append("| alpha-lambda missed at 70 % of life: the median RUL short / long "
                     "(actuators) | " + " | ".join(
                         f"{c['missed_early_0.7']:.0f} / {c['missed_late_0.7']:.0f}"
                         for c in camp) + " | - | - |")
        lines.append("| in hindsight (every actuator): the index's rate after 70 % of life "
                     "over its rate from 45 to 70 %, median (range) | " + " | ".join(
                         f"{c['rate_ratio_median']:.2f} ({c['rate_ratio_range'][0]:.2f}-"
                         f"{c['rate_ratio_range'][1]:.2f})" for c in camp) + " | - | - |")
        lines.append("| in hindsight: the index at failure, of the way from healthy to the "
                     "threshold (range) | " + " | ".join(
                         f"{c['u_fail_range'][0]:.2f}-{c['u_fail_range'][1]:.2f}"
                         for c in camp) + " | - | - |")
        lines.append("| in hindsight: the line through the tests from 45 to 70 % of life "
                     "within +-20 % of the RUL at 70 % | " + " | ".join(
                         _pct(c["line_ok"]) for c in camp) + " | - | - |")
        lines += ["", "The index at failure spreads (sd / mean) " + ", ".join(
            f"{c['cv_threshold']:.0%}" for c in camp) + " about the threshold and " + ", ".join(
            f"{c['cv_healthy']:.0%}" for c in camp) + " about a multiple of the healthy "
            "level (a `--failure Nx`).", ""]
        lines += ["Failure thresholds: " + ", ".join(
            f"{c['index']} {c['limit']:.4g}" for c in camp) + "; the CLI on each foreign "
            "file (50 actuators): " + ", ".join(f"{c['cli_s']:.0f} s" for c in camp) + "."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--campaign", metavar="DIR", help="trends.csv, campaign.json, cal.json "
                    "of `bench hums campaign --usage`")
    ap.add_argument("--healthy-campaign", default="3")
    ap.add_argument("--work", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--doc", default=None)
    ap.add_argument("--final-check", type=int, metavar="N", default=0,
                    help="instead: the final check, N trends of each law of "
                    "bench.hums.trend_check (section trend-final-check of --doc)")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import tempfile

    from bench import machine_description
    if a.final_check:
        t0 = time.perf_counter()
        fin = synthetic(a.final_check, final=True)
        text = final_markdown(fin, a.final_check, machine_description(),
                              time.perf_counter() - t0)
        print(text)
        if a.json:
            Path(a.json).write_text(json.dumps({"final_check": fin}, indent=1))
        if a.doc:
            from bench.hums.table import replace_section
            replace_section(a.doc, "trend-final-check", text)
            print(f"updated {a.doc}")
        return 0
    syn = synthetic(a.seeds)
    camp = calibrated = None
    if a.campaign:
        work = Path(a.work or tempfile.mkdtemp(prefix="trend-eval-"))
        work.mkdir(parents=True, exist_ok=True)
        d = Path(a.campaign)
        camp = [score_campaign(d, ix, a.healthy_campaign, work) for ix in CAMPAIGN_INDEXES]
        calibrated = json.loads((d / "campaign.json").read_text())["summary"]
    text = markdown(syn, camp, calibrated, a, machine_description())
    print(text)
    if a.json:
        Path(a.json).write_text(json.dumps({"synthetic": syn, "campaign": camp}, indent=1))
    if a.doc:
        from bench.hums.table import replace_section
        replace_section(a.doc, "trend-prognosis", text)
        print(f"updated {a.doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
