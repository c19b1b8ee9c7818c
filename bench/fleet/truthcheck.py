"""The fleet's RUL checked against a synthetic fleet's truth (`bench fleet synth`).

The store holds what the HUMS saw (the daily ground tests); ``fleet-truth.json`` holds
what it never saw: each actuator's schedule position s per day and its end of life, the
first day whose ground test is at s = 1 (`bench.fleet.synth.end_of_life_day`). The
status (`bench.fleet.status.status_of_series`) is evaluated **as of the end of each day
d**, from the tests up to that day only, and compared with the true remaining days
eol - d (from day d's test to the first test at the end of life; the truth has a
resolution of one day). Nothing here feeds back into the status: its thresholds and its
RUL are the thesis' (section 6.5), fixed before this check.

Measures (`check`):

- **predicted**: actuators reaching their end of life in the window that got a RUL
  (a finite RUL, not "failure level reached") on some day before it;
- **alpha-lambda** (Saxena et al.'s prognostic metric, as in `bench.hums.metrics`):
  at lambda = `LAMBDA` of the way from the warning crossing the status reports (t_w) to
  the end of life, the status as of the last day at or before that time; a hit if its
  RUL is within +-`ALPHA` of the true remaining days;
- **band coverage**: of every day with a RUL before the end of life, the fraction whose
  5-95 % band holds the true remaining days; the median relative error of those RULs;
- **false alarms**: actuator-days flagged "inspect this week" (`bench.fleet.report.
  inspect_reason`) while the true end of life is more than `FAR_DAYS` away (for an
  actuator that does not reach it in the window, at least D - d days away);
- **detection**: actuators flagged on the day of their end of life, and the days of
  notice (the first flag before the end of life, if any).
"""

from __future__ import annotations

import datetime as dt
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.fleet.report import inspect_reason
from bench.fleet.status import SERIES_COLUMNS, status_of_series

DAY_S = 86400.0
ALPHA = 0.3
"""alpha-lambda accuracy cone: +-30 % of the true remaining days."""
LAMBDA = 0.5
"""alpha-lambda time: half way from the warning crossing to the end of life."""
FAR_DAYS = 14.0
"""A flag with the end of life more than this many days away is a false alarm (the
report's own inspection horizon, `bench.fleet.report.INSPECT_RUL_DAYS`)."""


def load_truth(path: str | Path) -> dict[str, Any]:
    """``fleet-truth.json`` (a use-driven or time-driven fleet)."""
    try:
        truth = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise BenchError(f"{path}: cannot read the fleet truth: {exc}") from None
    if "fleet" not in truth or "days" not in truth:
        raise BenchError(f"{path}: not a fleet-truth.json of `bench fleet synth`")
    return truth


def end_of_life(row: dict[str, Any]) -> float:
    """The actuator's end-of-life day (inf: not in the window), either wear rule."""
    if "s" in row:
        hit = np.flatnonzero(np.asarray(row["s"], dtype=float) >= 1.0)
        return float(hit[0]) if len(hit) else math.inf
    life = float(row["life_days"])
    return float(math.ceil(life))


def check(series: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
    """Status as of each day against the truth (module docstring); `series` is
    `Store.series(SERIES_COLUMNS)`."""
    days = int(truth["days"])
    epoch = dt.datetime.fromisoformat(truth["epoch"]).timestamp()
    eol = {r["actuator"]: end_of_life(r) for r in truth["fleet"]}
    per_day = [{st.ident: st for st in status_of_series(
        series, as_of=epoch + (d + 1) * DAY_S - 1e-6)} for d in range(days)]
    actuators = []
    false_alarms, flagged_far, far_days = [], 0, 0
    for ident, e in sorted(eol.items()):
        a = _actuator(ident, e, per_day, days)
        if math.isfinite(e):
            actuators.append(a)
        for d in range(days):
            st = per_day[d].get(ident)
            remaining = e - d if math.isfinite(e) else days - d
            if st is None or remaining <= FAR_DAYS:
                continue
            far_days += 1
            why = inspect_reason(st)
            if why:
                flagged_far += 1
                false_alarms.append({"actuator": ident, "day": d, "remaining_days": remaining,
                                     "why": why})
    preds = [p for a in actuators for p in a["predictions"]]
    covered = [p["lo"] <= p["true"] <= p["hi"] for p in preds]
    rel = [abs(p["rul"] - p["true"]) / p["true"] for p in preds if p["true"] > 0]
    al = [a["alpha_lambda"] for a in actuators if a["alpha_lambda"] is not None]
    return {
        "seed": truth.get("seed"), "actuators": len(eol), "days": days,
        "wear": truth.get("wear", "time"), "alpha": ALPHA, "lambda": LAMBDA,
        "far_days": FAR_DAYS, "end_of_life_in_window": len(actuators),
        "with_rul_before_eol": sum(1 for a in actuators if a["predictions"]),
        "alpha_lambda_evaluated": len(al), "alpha_lambda_hits": sum(1 for h in al if h),
        "predictions": len(preds), "band_coverage": float(np.mean(covered)) if preds
        else math.nan, "median_rel_error": float(np.median(rel)) if rel else math.nan,
        "flagged_on_eol_day": sum(1 for a in actuators if a["flagged_at_eol"]),
        "notice_days": [a["notice_days"] for a in actuators],
        "far_actuator_days": far_days, "false_alarms": flagged_far,
        "false_alarm_list": false_alarms, "per_actuator": actuators}


def _actuator(ident: str, e: float, per_day: list[dict[str, Any]], days: int
              ) -> dict[str, Any]:
    """One actuator's predictions before its end of life `e` (days)."""
    preds, first_flag, t_w_day = [], None, None
    for d in range(min(int(e), days) if math.isfinite(e) else 0):
        st = per_day[d].get(ident)
        if st is None:
            continue
        if first_flag is None and inspect_reason(st):
            first_flag = d
        if math.isfinite(st.t_warning_s) and t_w_day is None:
            t_w_day = d  # the first day the status reports a warning crossing
        if math.isfinite(st.rul_days) and not (st.rul_days == 0.0 and st.rul_why):
            lo, hi = st.rul_band_days
            preds.append({"day": d, "rul": st.rul_days, "lo": lo, "hi": hi,
                          "true": e - d})
    hit = None
    if t_w_day is not None and math.isfinite(e):
        d_lam = math.floor(t_w_day + LAMBDA * (e - t_w_day))
        p = [q for q in preds if q["day"] == d_lam]
        if d_lam < e and p:
            hit = abs(p[0]["rul"] - p[0]["true"]) <= ALPHA * p[0]["true"]
        elif d_lam < e:
            hit = False  # no RUL at lambda: a miss
    flagged = None
    if math.isfinite(e) and int(e) < days and ident in per_day[int(e)]:
        flagged = bool(inspect_reason(per_day[int(e)][ident]))
    return {"actuator": ident, "end_of_life_day": e, "warning_day": t_w_day,
            "first_flag_day": first_flag,
            "notice_days": None if first_flag is None else e - first_flag,
            "flagged_at_eol": flagged, "alpha_lambda": hit, "predictions": preds}


def check_store(db: str | Path, truth_path: str | Path) -> dict[str, Any]:
    """`check` on a store file and a truth file."""
    from bench.fleet.store import Store
    with Store(str(db), read_only=True) as store:
        series = store.series(SERIES_COLUMNS)
    return check(series, load_truth(truth_path))


def markdown(res: dict[str, Any]) -> str:
    """The check's result as a Markdown table and a list per actuator."""
    cov = res["band_coverage"]
    rows = [
        ("actuators, days, wear rule, seed",
         f"{res['actuators']}, {res['days']}, {res['wear']}, {res['seed']}"),
        ("reach their end of life in the window", str(res["end_of_life_in_window"])),
        ("got a RUL before their end of life", str(res["with_rul_before_eol"])),
        (f"alpha-lambda hits (+-{100 * res['alpha']:.0f} % at lambda {res['lambda']:g})",
         f"{res['alpha_lambda_hits']} of {res['end_of_life_in_window']} "
         f"({res['alpha_lambda_evaluated']} had a warning crossing before the end of life)"),
        ("days with a RUL before the end of life", str(res["predictions"])),
        ("band coverage (true remaining days in the 5-95 % band)",
         "n/a" if not math.isfinite(cov) else f"{100 * cov:.0f} %"),
        ("median relative RUL error", "n/a" if not math.isfinite(res["median_rel_error"])
         else f"{100 * res['median_rel_error']:.0f} %"),
        ("flagged 'inspect this week' on the end-of-life day",
         f"{res['flagged_on_eol_day']} of {res['end_of_life_in_window']}"),
        ("days of notice (first flag before the end of life), per actuator",
         ", ".join("none" if n is None else f"{n:g}" for n in res["notice_days"])),
        (f"false alarms (flagged, end of life > {res['far_days']:g} days away)",
         f"{res['false_alarms']} of {res['far_actuator_days']} actuator-days"),
    ]
    out = ["| measure | value |", "|---|---|"]
    out += [f"| {a} | {b} |" for a, b in rows]
    out.append("")
    for a in res["per_actuator"]:
        pr = "; ".join(f"day {p['day']}: {p['rul']:.1f} [{p['lo']:.1f}, {p['hi']:.1f}] "
                       f"vs {p['true']:g}" for p in a["predictions"]) or "no RUL"
        out.append(f"- {a['actuator']}: end of life day {a['end_of_life_day']:g}, warning "
                   f"seen day {a['warning_day']}, first flag day {a['first_flag_day']}; {pr}")
    return "\n".join(out)
