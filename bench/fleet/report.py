"""`bench fleet report --out DIR`: static HTML with PNG figures from the fleet store.

``DIR/index.html`` is the overview a maintenance planner reads first: the actuators to
inspect this week and why, most urgent first (`inspect_reason`), then every actuator
with its status line (`bench.fleet.status`) and a figure of the fleet's Ci. One page per
actuator (``DIR/actuators/<id>.html``): Ci per test against the thesis' levels (0.93
threshold, 0.80 warning, 0.56 failure), with the RUL's failure-time band when there is
one; Cp and the lost motion; the usage (docs/usage.md); the
alerts (tests whose verdict is not HEALTHY) with links to the logs behind them.
Figures are drawn with matplotlib's Figure API: the fleet's into ``DIR/figures``, each
actuator's beside its page. An actuator's files are named by `bench.filenames.data_file`
(one bounded name per id, distinct ids distinct files).
"""

from __future__ import annotations

import datetime as dt
import html
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.fleet.schema import USAGE_COLUMNS
from bench.fleet.status import (
    DAY_S,
    ActuatorStatus,
    fleet_status,
    floats,
    judged_ci,
    rul_text,
    stored_level,
    urgency,
    usage_text,
)
from bench.hums import rul as R
from bench.verdict import Level

INSPECT_RUL_DAYS = 14.0
"""Inspect this week when the RUL's band starts within this many days."""
MAX_ALERTS = 60
CSS = ("body{font-family:sans-serif;max-width:1150px;margin:1.5em auto;color:#222}"
       "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #bbb;"
       "padding:3px 7px;text-align:left;font-size:14px}th{background:#eee}"
       ".v{display:inline-block;padding:2px 8px;border-radius:4px;color:#fff;"
       "font-weight:bold}.HEALTHY{background:#2a7}.DEGRADED{background:#c90}"
       ".WARNING{background:#d60}.FAILURE{background:#c22}.UNKNOWN{background:#777}"
       "img{max-width:100%}small{color:#555}")


def inspect_reason(st: ActuatorStatus) -> str | None:
    """Why `st` should be inspected this week (None: it need not be): its last test at
    WARNING or FAILURE, or its RUL band starting within INSPECT_RUL_DAYS."""
    why = []
    if st.level >= Level.WARNING:
        why.append(f"last test {st.verdict}: {st.reasons}")
    lo = st.rul_band_days[0]
    if st.level < Level.FAILURE and math.isfinite(st.rul_days) and lo <= INSPECT_RUL_DAYS:
        why.append(f"RUL {rul_text(st)}: failure level {R.FAILURE} may be reached within "
                   f"{max(lo, 0.0):.0f} days")
    return "; ".join(why) or None


def watch_reason(st: ActuatorStatus) -> str | None:
    """Why `st` is to be watched (not inspected yet): DEGRADED, or Ci below the
    threshold with no RUL yet."""
    if st.level == Level.DEGRADED:
        return f"last test {st.level.name}: {st.reasons}"
    if math.isfinite(st.t_threshold_s):
        return st.rul_why or f"Ci below the threshold {R.THRESHOLD}"
    return None


def write_report(store: Any, out_dir: str | Path) -> Path:
    """The overview and the actuator pages into `out_dir`; returns the overview's path."""
    out = Path(out_dir)
    try:
        (out / "figures").mkdir(parents=True, exist_ok=True)
        (out / "actuators").mkdir(exist_ok=True)
    except OSError as exc:
        raise BenchError(f"{out}: cannot create the report directory: {exc}") from None
    from bench.filenames import data_file
    rows = sorted(fleet_status(store), key=urgency)
    if not rows:
        raise BenchError(f"{store.path}: the fleet store has no runs yet")
    data = store.series(("ci", "ci_harmonic", "cp", "lost_motion_m", "verdict", "reasons",
                         "path", *USAGE_COLUMNS))
    ids = np.asarray(data["actuator_id"], dtype=object)
    _fleet_figure(rows, data, ids, out / "figures" / "fleet-ci.png")
    for st in rows:
        m = ids == st.ident
        sub = {k: np.asarray(v)[m] for k, v in data.items()}
        page = data_file(out / "actuators", st.ident, ".html")
        page.write_text(_actuator_page(st, sub, out))
    index = out / "index.html"
    index.write_text(_overview(rows, store))
    return index


def _slug(ident: str) -> str:
    """The actuator's file name stem (`bench.filenames.safe_name`: one name, bounded,
    distinct ids give distinct names)."""
    from bench.filenames import safe_name
    return safe_name(ident)


def _href(ident: str) -> str:
    """The actuator page's file name, quoted for a link."""
    from urllib.parse import quote
    return quote(f"{_slug(ident)}.html")


def _when(t_s: float) -> str:
    return dt.datetime.fromtimestamp(t_s, dt.UTC).strftime("%Y-%m-%d %H:%M")


def _head(title: str) -> list[str]:
    return ["<!doctype html><html><head><meta charset='utf-8'>",
            f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>"]


def _overview(rows: list[ActuatorStatus], store: Any) -> str:
    e = html.escape
    inspect = [(st, inspect_reason(st)) for st in rows]
    inspect = [(st, w) for st, w in inspect if w]
    watch = [(st, watch_reason(st)) for st in rows if not inspect_reason(st)]
    watch = [(st, w) for st, w in watch if w]
    n_fail = len(store.failures())
    last = max(st.last_time_s for st in rows)
    p = _head("Fleet health: inspection plan")
    p.append(f"<h1>Fleet health: inspection plan</h1><p>{len(rows)} actuators, "
             f"{sum(st.tests for st in rows)} ground tests up to {_when(last)} UTC"
             + (f"; {n_fail} logs could not be read (listed at the end)" if n_fail else "")
             + ".</p>")
    p.append(f"<h2>Inspect this week ({len(inspect)})</h2>")
    if inspect:
        p.append("<table><tr><th>#</th><th>actuator</th><th>level</th><th>Ci</th>"
                 "<th>trend Ci/day</th><th>RUL (days) [90 % band]</th><th>why</th></tr>")
        for k, (st, why) in enumerate(inspect, 1):
            p.append(f"<tr><td>{k}</td>{_id_cell(st)}<td><span class='v {st.verdict}'>"
                     f"{st.verdict}</span></td><td>{st.ci_last:.3f}</td>"
                     f"<td>{_slope(st)}</td><td>{e(rul_text(st))}</td><td>{e(why or '')}</td></tr>")
        p.append("</table>")
    else:
        p.append("<p>No actuator needs an inspection this week.</p>")
    p.append(f"<h2>Watch ({len(watch)})</h2>")
    if watch:
        p.append("<table><tr><th>actuator</th><th>level</th><th>Ci</th><th>trend Ci/day"
                 "</th><th>why</th></tr>")
        for st, why in watch:
            p.append(f"<tr>{_id_cell(st)}<td><span class='v {st.verdict}'>{st.verdict}"
                     f"</span></td><td>{st.ci_last:.3f}</td><td>{_slope(st)}</td>"
                     f"<td>{e(why or '')}</td></tr>")
        p.append("</table>")
    p.append("<h2>Fleet</h2><img alt='Ci of every actuator' src='figures/fleet-ci.png'>")
    p.append("<table><tr><th>actuator</th><th>tests</th><th>last test (UTC)</th>"
             "<th>level</th><th>Ci</th><th>trend Ci/day</th><th>RUL (days)</th>"
             "<th>usage consumed</th></tr>")
    for st in rows:
        p.append(f"<tr>{_id_cell(st)}<td>{st.tests}</td><td>{_when(st.last_time_s)}</td>"
                 f"<td><span class='v {st.verdict}'>{st.verdict}</span></td>"
                 f"<td>{st.ci_last:.3f}</td><td>{_slope(st)}</td><td>{e(rul_text(st))}</td>"
                 f"<td>{e(usage_text(st))}</td></tr>")
    p.append("</table>")
    if n_fail:
        p.append("<h2>Logs that could not be read</h2><table><tr><th>actuator</th><th>log"
                 "</th><th>error</th></tr>" + "".join(
                     f"<tr><td>{e(a or '')}</td><td>{e(path)}</td><td>{e(err)}</td></tr>"
                     for a, path, err in store.failures()[:200]) + "</table>")
    p.append(_footer())
    return "\n".join(p)


def _footer() -> str:
    return (f"<p><small>Ci is the current fidelity coefficient (eq. 6.6) of each ground test "
            f"against the monitoring model, on the command frequency and its harmonics. "
            f"Levels (thesis section 6.5): threshold {R.THRESHOLD}, warning {R.WARNING}, "
            f"failure {R.FAILURE}. RUL: the thesis' cubic on Ci over the daily tests from "
            f"the threshold crossing, extrapolated to {R.FAILURE}, band 5-95 % of a "
            f"bootstrap. Inspect this week: last test WARNING or FAILURE, or the RUL band "
            f"starting within {INSPECT_RUL_DAYS:.0f} days. Usage: docs/usage.md (L10 life "
            "consumed by Palmgren-Miner).</small></p></body></html>")


def _id_cell(st: ActuatorStatus) -> str:
    return (f"<td><a href='actuators/{html.escape(_href(st.ident))}'>"
            f"{html.escape(st.ident)}</a></td>")


def _slope(st: ActuatorStatus) -> str:
    return "-" if not math.isfinite(st.slope_per_day) else f"{st.slope_per_day:+.4f}"


USAGE_ROWS = (("nut travel", "travel_m", 1.0, "m"), ("screw revolutions", "screw_revs", 1.0, ""),
              ("reversals", "reversals", 1.0, ""), ("L10 life consumed", "life_consumed",
                                                      100.0, "%"),
              ("I^2 t", "i2t_a2s", 1.0, "A^2 s"), ("winding above 400 K", "time_hot_s", 1.0,
                                                   "s"))


def _usage_table(sub: dict[str, np.ndarray]) -> str:
    """The actuator's usage summed over its runs, and the equivalent load of the latest
    run that had one (NULL columns, runs without a load signal, are left out)."""
    rows = []
    for label, col, scale, unit in USAGE_ROWS:
        v = _f(sub[col])
        ok = np.isfinite(v)
        txt = f"{scale * float(v[ok].sum()):.4g} {unit}" if ok.any() else "n/a"
        rows.append(f"<tr><td>{label}</td><td>{txt}</td><td>{int(ok.sum())}</td></tr>")
    fm = _f(sub["equivalent_load_n"])
    last = fm[np.isfinite(fm)]
    rows.append("<tr><td>equivalent load F_m, latest run</td><td>"
                + (f"{last[-1]:.0f} N" if len(last) else "n/a") + "</td><td></td></tr>")
    return ("<table><tr><th>usage (sum of runs)</th><th>value</th><th>runs</th></tr>"
            + "".join(rows) + "</table>")


def _actuator_page(st: ActuatorStatus, sub: dict[str, np.ndarray], out: Path) -> str:
    e = html.escape
    from urllib.parse import quote

    from bench.filenames import data_file
    fig = data_file(out / "actuators", st.ident, ".png")     # beside its page
    _actuator_figure(st, sub, fig)
    p = _head(f"{st.ident}: health")
    p.append(f"<p><a href='../index.html'>fleet overview</a></p><h1>{e(st.ident)} "
             f"<span class='v {st.verdict}'>{st.verdict}</span></h1>")
    why = inspect_reason(st) or watch_reason(st)
    p.append("<table>" + "".join(f"<tr><th>{k}</th><td>{e(v)}</td></tr>" for k, v in (
        ("tests", str(st.tests)), ("last test (UTC)", _when(st.last_time_s)),
        ("last verdict", f"{st.verdict}: {st.reasons}"), ("Ci (last)", f"{st.ci_last:.3f}"),
        ("trend", f"{_slope(st)} Ci per day over the last tests"),
        ("RUL (days) [90 % band]", rul_text(st)), ("usage consumed", usage_text(st)),
        ("action", why or "none"))) + "</table>")
    p.append(f"<h2>Index trends</h2><img alt='trends' src='{e(quote(fig.name))}'>")
    p.append("<h2>Usage</h2>" + _usage_table(sub))
    lvl = np.array([int(stored_level(v)) for v in sub["verdict"]])
    alerts = np.flatnonzero(lvl > Level.HEALTHY)[::-1][:MAX_ALERTS]
    n_alerts = int((lvl > Level.HEALTHY).sum())
    p.append(f"<h2>Alerts ({n_alerts} tests not {Level.HEALTHY.name}"
             + (f", latest {MAX_ALERTS} shown" if n_alerts > MAX_ALERTS else "")
             + ")</h2>")
    if len(alerts):
        p.append("<table><tr><th>test (UTC)</th><th>verdict</th><th>Ci</th><th>why</th>"
                 "<th>log</th></tr>")
        ci = judged_ci(_f(sub["ci"]), _f(sub["ci_harmonic"]))
        for k in alerts:
            path = str(sub["path"][k])
            href = os.path.relpath(path, out / "actuators") if path else ""
            p.append(f"<tr><td>{_when(float(sub['run_time'][k]))}</td><td><span class='v "
                     f"{sub['verdict'][k]}'>{sub['verdict'][k]}</span></td>"
                     f"<td>{ci[k]:.3f}</td><td>{e(str(sub['reasons'][k]))}</td>"
                     f"<td><a href='{e(href)}'>{e(Path(path).name)}</a></td></tr>")
        p.append("</table>")
    else:
        p.append(f"<p>None: every test {Level.HEALTHY.name}.</p>")
    p.append(_footer())
    return "\n".join(p)


_f = floats


def _levels(ax: Any) -> None:
    for lv, c, name in ((R.THRESHOLD, "C2", "threshold"), (R.WARNING, "C1", "warning"),
                        (R.FAILURE, "C3", "failure")):
        ax.axhline(lv, color=c, ls="--", lw=1, label=f"{name} {lv}")


def _actuator_figure(st: ActuatorStatus, sub: dict[str, np.ndarray], path: Path) -> None:
    from matplotlib.figure import Figure
    t = _f(sub["run_time"])
    when = (t * 1e6).astype("datetime64[us]")
    ci = judged_ci(_f(sub["ci"]), _f(sub["ci_harmonic"]))
    fig = Figure(figsize=(11, 3.6))
    ax = fig.subplots(1, 2)
    ax[0].plot(when, ci, "k.-", ms=4, lw=0.8, label="Ci (15 harmonics)")
    ax[0].plot(when, _f(sub["ci"]), ".", color="0.6", ms=3, label="Ci broadband")
    _levels(ax[0])
    if math.isfinite(st.rul_days):
        lo, hi = st.rul_band_days
        t0 = np.datetime64(int(st.last_time_s), "s")
        med = t0 + np.timedelta64(int(st.rul_days * DAY_S), "s")
        ax[0].axvspan(t0 + np.timedelta64(int(lo * DAY_S), "s"),
                      t0 + np.timedelta64(int(min(hi, 10 * max(st.rul_days, 1)) * DAY_S),
                                          "s"), color="C3", alpha=0.15,
                      label="failure time, 90 % band")
        ax[0].axvline(med, color="C3", lw=1, label="failure time, median")
    ax[0].set(title="current fidelity per ground test", ylabel="Ci")
    ax[0].legend(fontsize=7, loc="lower left")
    ax[1].plot(when, 1e6 * _f(sub["lost_motion_m"]), "C0.", ms=4, label="lost motion (um)")
    ax2 = ax[1].twinx()
    ax2.plot(when, _f(sub["cp"]), "C1.", ms=3, label="Cp")
    ax2.set_ylabel("Cp")
    ax[1].set(title="backlash indicators per ground test", ylabel="um")
    ax[1].legend(fontsize=7, loc="upper left")
    ax2.legend(fontsize=7, loc="lower right")
    for a in ax:
        a.tick_params(axis="x", labelrotation=30, labelsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def _fleet_figure(rows: list[ActuatorStatus], data: dict[str, Any], ids: np.ndarray,
                  path: Path) -> None:
    from matplotlib.figure import Figure
    t = _f(data["run_time"])
    ci = judged_ci(_f(data["ci"]), _f(data["ci_harmonic"]))
    fig = Figure(figsize=(11, 3.4))
    ax = fig.subplots()
    urgent = {st.ident for st in rows if inspect_reason(st)}
    for st in rows:
        m = ids == st.ident
        when = (t[m] * 1e6).astype("datetime64[us]")
        if st.ident in urgent:
            ax.plot(when, ci[m], "-", lw=1.2, label=st.ident if len(urgent) <= 8 else None)
        else:
            ax.plot(when, ci[m], "-", color="0.7", lw=0.6)
    _levels(ax)
    ax.set(title="Ci per ground test, every actuator (colour: inspect this week)",
           ylabel="Ci")
    ax.legend(fontsize=7, loc="lower left", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
