"""`bench fleet report --out DIR`: static HTML with PNG figures from the fleet store.

``DIR/index.html`` is the overview a maintenance planner reads first: the actuators to
inspect this week and why, most urgent first (`inspect_reason`), then every actuator
with its status line (`bench.fleet.status`; the same values in ``DIR/status.json``) and a
figure of the fleet's Ci. One page per
actuator (``DIR/actuators/<id>.html``): Ci per test against the thesis' levels (0.93
threshold, 0.80 warning, 0.56 failure), with the RUL's failure-time band when there is
one; Cp and the lost motion; the usage (docs/usage.md); the
alerts (tests whose verdict is not HEALTHY) with links to the logs behind them.
Figures are drawn with matplotlib's Figure API: the fleet's into ``DIR/figures``, each
actuator's beside its page. An actuator's files are named by `bench.core.filenames.data_file`
(one bounded name per id, distinct ids distinct files).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.core.jsonsafe import json_safe
from bench.core.verdict import Level
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

INSPECT_RUL_DAYS = 14.0
"""Inspect this week when the RUL's band starts within this many days."""
MAX_ALERTS = 60


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
    from bench.core.filenames import data_file
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
    (out / "status.json").write_text(json.dumps(
        json_safe([status_record(st) for st in rows]), indent=1))
    return index


def _slug(ident: str) -> str:
    """The actuator's file name stem (`bench.core.filenames.safe_name`: one name, bounded,
    distinct ids give distinct names)."""
    from bench.core.filenames import safe_name
    return safe_name(ident)


def _href(ident: str) -> str:
    """The actuator page's file name, quoted for a link."""
    from urllib.parse import quote
    return quote(f"{_slug(ident)}.html")


def _when(t_s: float) -> str:
    return dt.datetime.fromtimestamp(t_s, dt.UTC).strftime("%Y-%m-%d %H:%M")


def _level_cells(st: ActuatorStatus) -> list[Any]:
    """The actuator (a link to its page), its level badge and its last Ci."""
    from bench.reports import badge, link
    return [link(f"actuators/{_href(st.ident)}", st.ident), badge(st.verdict),
            f"{st.ci_last:.3f}"]


def status_record(st: ActuatorStatus) -> dict[str, Any]:
    """The values the overview's fleet table shows of `st` (``status.json``)."""
    lo, hi = st.rul_band_days
    return {"actuator": st.ident, "tests": st.tests, "last_test_utc": _when(st.last_time_s),
            "level": st.verdict, "ci": st.ci_last, "slope_ci_per_day": st.slope_per_day,
            "rul_days": st.rul_days, "rul_band_days": [lo, hi], "rul": rul_text(st),
            "life_consumed": st.life_consumed, "usage": usage_text(st),
            "reasons": st.reasons}


def fleet_table(rows: list[ActuatorStatus]) -> Any:
    """Every actuator's status line (the overview's summary table)."""
    from bench.reports import Table
    return Table(["actuator", "tests", "last test (UTC)", "level", "Ci", "trend Ci/day",
                  "RUL (days)", "usage consumed"],
                 [[c[0], str(st.tests), _when(st.last_time_s), c[1], c[2], _slope(st),
                   rul_text(st), usage_text(st)] for st in rows
                  for c in [_level_cells(st)]],
                 numeric=[False, True, False, False, True, True, False, False],
                 role="summary")


def _overview(rows: list[ActuatorStatus], store: Any) -> str:
    from bench.reports import Document, Figure, Heading, Paragraph, Table, render_document
    inspect = [(st, inspect_reason(st)) for st in rows]
    inspect = [(st, w) for st, w in inspect if w]
    watch = [(st, watch_reason(st)) for st in rows if not inspect_reason(st)]
    watch = [(st, w) for st, w in watch if w]
    failures = store.failures()
    last = max(st.last_time_s for st in rows)
    doc = Document([Paragraph(
        f"{len(rows)} actuators, {sum(st.tests for st in rows)} ground tests up to "
        f"{_when(last)} UTC" + (f"; {len(failures)} logs could not be read (listed at the "
                                 "end)" if failures else "") + "."),
        Heading(f"Inspect this week ({len(inspect)})")])
    num = [False, False, False, True, True, False, False]
    if inspect:
        doc.add(Table(["#", "actuator", "level", "Ci", "trend Ci/day", "RUL (days) [90 % band]",
                       "why"], [[str(k), *_level_cells(st), _slope(st), rul_text(st), why or ""]
                                for k, (st, why) in enumerate(inspect, 1)],
                      numeric=[True, *num[1:]]))
    else:
        doc.add("No actuator needs an inspection this week.")
    doc.add(Heading(f"Watch ({len(watch)})"))
    if watch:
        doc.add(Table(["actuator", "level", "Ci", "trend Ci/day", "why"],
                      [[*_level_cells(st), _slope(st), why or ""] for st, why in watch],
                      numeric=num[1:-1]))
    doc.add(Heading("Fleet"), Figure("Ci of every actuator", src="figures/fleet-ci.png"),
            fleet_table(rows))
    if failures:
        doc.add(Heading("Logs that could not be read"),
                Table(["actuator", "log", "error"], [[a or "", path, err] for a, path, err
                                                     in failures[:200]], numeric=[False] * 3))
    return render_document(doc, title="Fleet health: inspection plan", footer=_footer())


def _footer() -> Any:
    from bench.reports import Document, Paragraph
    return Document([Paragraph(
        f"Ci is the current fidelity coefficient (eq. 6.6) of each ground test "
        f"against the monitoring model, on the command frequency and its harmonics. "
        f"Levels (thesis section 6.5): threshold {R.THRESHOLD}, warning {R.WARNING}, "
        f"failure {R.FAILURE}. RUL: the thesis' cubic on Ci over the daily tests from "
        f"the threshold crossing, extrapolated to {R.FAILURE}, band 5-95 % of a "
        f"bootstrap. Inspect this week: last test WARNING or FAILURE, or the RUL band "
        f"starting within {INSPECT_RUL_DAYS:.0f} days. Usage: docs/usage.md (L10 life "
        "consumed by Palmgren-Miner).")])


def _slope(st: ActuatorStatus) -> str:
    return "-" if not math.isfinite(st.slope_per_day) else f"{st.slope_per_day:+.4f}"


USAGE_ROWS = (("nut travel", "travel_m", 1.0, "m"), ("screw revolutions", "screw_revs", 1.0, ""),
              ("reversals", "reversals", 1.0, ""), ("L10 life consumed", "life_consumed",
                                                      100.0, "%"),
              ("I^2 t", "i2t_a2s", 1.0, "A^2 s"), ("winding above 400 K", "time_hot_s", 1.0,
                                                   "s"))


def _usage_table(sub: dict[str, np.ndarray]) -> Any:
    """The actuator's usage summed over its runs, and the equivalent load of the latest
    run that had one (NULL columns, runs without a load signal, are left out)."""
    from bench.reports import Table
    rows = []
    for label, col, scale, unit in USAGE_ROWS:
        v = _f(sub[col])
        ok = np.isfinite(v)
        txt = f"{scale * float(v[ok].sum()):.4g} {unit}" if ok.any() else "n/a"
        rows.append([label, txt, str(int(ok.sum()))])
    fm = _f(sub["equivalent_load_n"])
    last = fm[np.isfinite(fm)]
    rows.append(["equivalent load F_m, latest run", f"{last[-1]:.0f} N" if len(last) else
                 "n/a", ""])
    return Table(["usage (sum of runs)", "value", "runs"], rows, numeric=[False, True, True])


def _actuator_page(st: ActuatorStatus, sub: dict[str, np.ndarray], out: Path) -> str:
    from urllib.parse import quote

    from bench import reports as page
    from bench.core.filenames import data_file
    fig = data_file(out / "actuators", st.ident, ".png")     # beside its page
    _actuator_figure(st, sub, fig)
    why = inspect_reason(st) or watch_reason(st)
    doc = page.Document([page.Paragraph(page.badge(st.verdict)), page.Table(["quantity", "value"], [list(kv) for kv in (
        ("tests", str(st.tests)), ("last test (UTC)", _when(st.last_time_s)),
        ("last verdict", f"{st.verdict}: {st.reasons}"), ("Ci (last)", f"{st.ci_last:.3f}"),
        ("trend", f"{_slope(st)} Ci per day over the last tests"),
        ("RUL (days) [90 % band]", rul_text(st)), ("usage consumed", usage_text(st)),
        ("action", why or "none"))], numeric=[False, False], role="summary"),
        page.Heading("Index trends"), page.Figure("", src=quote(fig.name), alt="trends"),
        page.Heading("Usage"), _usage_table(sub)])
    lvl = np.array([int(stored_level(v)) for v in sub["verdict"]])
    alerts = np.flatnonzero(lvl > Level.HEALTHY)[::-1][:MAX_ALERTS]
    n_alerts = int((lvl > Level.HEALTHY).sum())
    doc.add(page.Heading(f"Alerts ({n_alerts} tests not {Level.HEALTHY.name}"
                    + (f", latest {MAX_ALERTS} shown" if n_alerts > MAX_ALERTS else "")
                    + ")"))
    if len(alerts):
        ci = judged_ci(_f(sub["ci"]), _f(sub["ci_harmonic"]))
        rows = []
        for k in alerts:
            path = str(sub["path"][k])
            href = os.path.relpath(path, out / "actuators") if path else ""
            rows.append([_when(float(sub["run_time"][k])), page.badge(str(sub["verdict"][k])),
                         f"{ci[k]:.3f}", str(sub["reasons"][k]),
                         page.link(quote(href), Path(path).name)])
        doc.add(page.Table(["test (UTC)", "verdict", "Ci", "why", "log"], rows,
                      numeric=[False, False, True, False, False]))
    else:
        doc.add(f"None: every test {Level.HEALTHY.name}.")
    return page.render_document(doc, title=f"{st.ident}: health", footer=_footer(),
                           nav=[("../index.html", "fleet overview")])


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
