"""`bench hums report LOG...`: a self-contained HTML health report of one or more logs.

A log is a candump ``.log`` decoded through the DBC (`bench.bus.logs.trace_from_log`,
when that module is installed) or a trace table (``.npz``, ``.csv``, ``.parquet``,
`bench.signals.trace.Trace.load`). The report compares each log with the monitoring model
driven by the log's own set-points and gives, for a reader who never ran the bench:
what was run, the indexes with their healthy ranges, a verdict, the per-period trend
and, for long periodic logs, the fused backlash estimate and the RUL with its band.
Figures are embedded as base64 PNG, so the HTML file is all there is.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.core.jsonsafe import json_safe
from bench.core.verdict import Verdict
from bench.hums import indexes as I
from bench.hums import monitor as M
from bench.hums.verdict import index_record, judge, judged_ci
from bench.signals import estimators as E
from bench.signals.trace import MEASURED, MODE_POSITION, MODE_SPEED, Trace
from plant_rt.params import PlantParams

MIN_PERIODS_FOR_TREND = 6


def command_period_hz(trace: Trace) -> float:
    """The command's frequency (Hz) as a period (`estimators.fundamental_hz`, periodic):
    the trace's metadata, else the strongest line of the set-point spectrum (position or
    speed, by the log's mode; NaN for a non-periodic command such as a step)."""
    f0 = E.fundamental_hz(trace.meta.get("fundamental_hz"))
    if math.isfinite(f0):
        return f0
    mode = _mode(trace)
    col = "setpoint_position_m" if mode == MODE_POSITION else "setpoint_speed_rad_s"
    if col not in trace or len(trace) < 64:
        return math.nan
    return E.fundamental_hz((), np.nan_to_num(trace[col]), trace.dt, periodic=True)


def _mode(trace: Trace) -> int:
    if "mode" not in trace:
        return 0
    m = trace["mode"]
    m = m[np.isfinite(m)]
    return int(np.bincount(m.astype(int)).argmax()) if len(m) else 0


# --- analysis ---------------------------------------------------------------------------

@dataclass
class LogAnalysis:
    name: str
    trace: Trace
    nominal: Trace
    f0_hz: float
    indexes: I.Indexes
    verdict: Verdict
    period_table: dict[str, np.ndarray] = field(default_factory=dict)
    fused: Any = None
    missing: list[str] = field(default_factory=list)
    bridged: dict[str, int] = field(default_factory=dict)   # signal -> samples bridged
    notes: list[str] = field(default_factory=list)          # what the log lost / repeated
    rul_note: str = ""                                       # why there is no RUL

    @property
    def reasons(self) -> list[str]:
        """The verdict's reasons."""
        return list(self.verdict.reasons)


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "ema-hums-bench"


def cached_calibration(params: PlantParams, kp: float, progress: bool = False) -> Any:
    """The fused predictor's calibration for `params`, cached on disk by parameter hash
    (building it runs ~20 short simulations)."""
    from bench.hums import calibration as R
    key = hashlib.sha256((params.to_json() + f"{kp:.6f}v{R.CALIBRATION_VERSION}").encode()
                         ).hexdigest()[:16]
    path = _cache_dir() / f"calibration-{key}.json"
    if path.exists():
        try:
            return R.Calibration(**json.loads(path.read_text()))
        except (OSError, TypeError, ValueError):
            pass
    cal = R.calibrate(params, kp, progress=progress)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(cal.to_json()))
    except OSError:
        pass
    return cal


MIN_VERDICT_S = 0.1
"""Shortest log given a verdict: a tenth of a second (100 SYNC periods at 1 kHz). The
shortest profile, the 0.3 s velocity step, is three times that; over a shorter window
the start transient of the loops (tens of ms) outweighs what the indexes integrate."""


def analyse(trace: Trace, name: str, params: PlantParams | None = None,
            rul: bool = True, period_s: float | None = None,
            progress: bool = False) -> LogAnalysis:
    """Indexes, verdict and (long periodic logs) trend and RUL of one trace.

    Missing samples (lost SYNCs, missing frames, NaN rows) are bridged by interpolation
    when the gaps are short (`bench.hums.indexes.BRIDGE_MAX_SAMPLES`); longer ones make
    the indexes that read the signal unavailable, with the reason. A log shorter than
    MIN_VERDICT_S gets no index and no verdict (UNKNOWN)."""
    params = params or PlantParams()
    trace.require(M.NOMINAL_DRIVE, f"{name}: the HUMS report (set-points drive the "
                  "monitoring model)")
    meas = trace.measured()
    have_i = "current_a" in meas and np.isfinite(meas["current_a"]).any()
    have_x = "position_m" in meas and np.isfinite(meas["position_m"]).any()
    if not (have_i or have_x):
        raise BenchError(f"{name}: the HUMS report needs current_a or position_m, which "
                         "this log does not have")
    missing = [c for c in ("current_a", "position_m", "motor_speed_rad_s", "motor_angle_rad")
               if c not in meas or not np.isfinite(meas[c]).any()]
    notes = _log_notes(meas.meta)
    short = _too_short(meas)
    if short:
        return _unjudged(meas, name, short, missing, notes)
    gaps = I.signal_gaps(meas, MEASURED[1:])
    meas = I.bridge(meas, gaps)
    bridged = {c: g.missing for c, g in gaps.items() if g.bridgeable}
    blocked = {c: g.describe(meas.t) for c, g in gaps.items() if not g.bridgeable}
    if bridged:
        notes.append("short gaps bridged by interpolation: " + ", ".join(
            f"{c} {k} sample{'s' if k > 1 else ''}" for c, k in bridged.items()))
    fit, _ = M.fitted(params)
    kp = fit.gain_rad_s_per_m
    nom = M.nominal_for(meas, kp, M.MonitorParams.from_plant(params))
    f0 = 1.0 / period_s if period_s else command_period_hz(meas)
    meas.meta["fundamental_hz"] = f0
    ix = I.compare(meas, nom, f0_hz=f0 if math.isfinite(f0) else None, need=())
    I.mark_unavailable(ix, blocked, M.NOMINAL_DRIVE)
    out = LogAnalysis(name, meas, nom, f0, ix, Verdict.unknown(()), missing=missing,
                      bridged=bridged, notes=notes)
    n_periods = int(len(meas) * meas.dt * f0) if math.isfinite(f0) else 0
    trend_blocked = set(blocked) & {"current_a", "position_m", *M.NOMINAL_DRIVE}
    if trend_blocked:
        notes.append("no trend or RUL: " + "; ".join(blocked[c] for c in sorted(trend_blocked)))
    elif have_i and have_x and n_periods >= 1:
        rows = list(I.period_indexes(meas, nom, 1.0 / f0, kin=None))
        out.period_table = I.as_table(rows)
    out.rul_note = _no_rul(rul, f0, n_periods, have_i and have_x, trend_blocked)
    if not out.rul_note and out.period_table:
        from bench.hums import fusion as R
        cal = cached_calibration(M.nominal_plant(params), kp, progress)
        t_end = out.period_table["t_start_s"] + 1.0 / f0
        out.fused = (R.FusedPredictor(cal).run(t_end, out.period_table), cal, t_end)
    out.verdict = verdict(out)
    return out


def _no_rul(rul: bool, f0: float, n_periods: int, both: bool, blocked: set[str]) -> str:
    """Why the log gets no fused RUL ("" when it gets one)."""
    if not rul:
        return ("not computed: skipped here (`bench hums report LOG` computes it on a "
                f"periodic log of >= {MIN_PERIODS_FOR_TREND} command periods)")
    if blocked:
        return ("signals missing: " + ", ".join(sorted(blocked))
                + " missing over a stretch too long to bridge")
    if not both:
        return "needs current and position: the fused predictor reads current_a and position_m"
    if not math.isfinite(f0):
        return "not periodic: the fused predictor reads command periods"
    if n_periods < MIN_PERIODS_FOR_TREND:
        return (f"{n_periods} command period{'s' if n_periods != 1 else ''}: the fused "
                f"predictor needs >= {MIN_PERIODS_FOR_TREND}")
    return ""


def _log_notes(meta: dict[str, Any]) -> list[str]:
    """What the decoder found wrong with the log (lost SYNCs, missing frames, ...)."""
    try:
        from bench.signals.integrity import integrity
    except ImportError:        # the bus part is not installed: no decoded logs either
        return []
    return integrity(meta)


def _too_short(meas: Trace) -> str | None:
    """Why `meas` is too short for a verdict (None when it is long enough)."""
    n = len(meas)
    dt = meas.dt if n > 1 else float(meas.meta.get("period_s") or 1e-3)
    need = math.ceil(MIN_VERDICT_S / dt - 1e-9)
    if n >= 2 and n >= need:
        return None
    return f"({n} row{'s' if n != 1 else ''}, at least {need} needed)"


def _unjudged(meas: Trace, name: str, why: str, missing: list[str],
              notes: list[str]) -> LogAnalysis:
    """The analysis of a log too short for any index: nothing computed, no verdict."""
    t = meas.t
    ix = I.Indexes(float(t[0]) if len(t) else 0.0, float(t[-1]) if len(t) else 0.0)
    ix.unavailable = {k: f"not available {why}" for k in I.INDEX_SIGNALS}
    nom = Trace({"t_s": t.copy(), **{c: np.full(len(t), np.nan)
                                      for c in ("position_m", "current_a")}})
    out = LogAnalysis(name, meas, nom, math.nan, ix, Verdict.unknown(()), missing=missing,
                      notes=notes, rul_note=f"log too short: {why}")
    out.verdict = verdict(out)
    return out


def verdict(a: LogAnalysis) -> Verdict:
    """The log's verdict (`bench.hums.verdict.judge` on the log's indexes,
    its most frequent mode and its fused backlash estimate)."""
    return judge(a.indexes, _mode(a.trace), a.fused)


# --- rendering -----------------------------------------------------------------------------

def _figures(a: LogAnalysis) -> list[tuple[str, str]]:
    """(caption, base64 PNG) of each figure of one log (matplotlib `Figure` API)."""
    from matplotlib.figure import Figure

    from bench.reports import png_base64
    out = []
    tr, nm = a.trace, a.nominal
    t = tr.t
    n = len(t)
    show = slice(0, min(n, int(4.0 / max(tr.dt, 1e-9)))) if n * tr.dt > 8 else slice(0, n)
    fig = Figure(figsize=(11, 3.4))
    ax = fig.subplots(1, 2)
    if "position_m" in tr:
        ax[0].plot(t[show], 1e3 * tr["position_m"][show], "k", lw=1.5, label="log (LVDT)")
        ax[0].plot(t[show], 1e3 * nm["position_m"][show], "C0--", label="nominal model")
    ax[0].set(title="nut position", xlabel="t (s)", ylabel="mm")
    legend_above_data(ax[0], ncol=2, fontsize=8)
    if "current_a" in tr:
        ax[1].plot(t[show], tr["current_a"][show], "k", lw=1, label="log")
        ax[1].plot(t[show], nm["current_a"][show], "C0--", label="nominal model")
    ax[1].set(title="motor current", xlabel="t (s)", ylabel="A")
    legend_above_data(ax[1], ncol=2, fontsize=8)
    out.append(("Measured signals against the nominal model"
                + (" (first 4 s)" if show.stop < n else ""), png_base64(fig)))
    if "current_a" in tr and np.isfinite(tr["current_a"]).all() and n >= 64:
        fig = Figure(figsize=(6, 3.2))
        ax1 = fig.subplots()
        f, amp = I.amplitude_spectrum(tr["current_a"], tr.dt)
        fn, an = I.amplitude_spectrum(nm["current_a"], tr.dt)
        ax1.plot(fn, an, "C0", lw=2, label="nominal model")
        ax1.plot(f, amp, "k", lw=1, label="log")
        top = 20 * a.f0_hz if math.isfinite(a.f0_hz) else 50.0
        ax1.set(xlim=(0, top), title="current spectrum (Hann, amplitude)", xlabel="Hz",
                ylabel="A")
        ax1.legend(fontsize=8)
        out.append(("Current spectrum (eq. 6.3)", png_base64(fig)))
    pt = a.period_table
    if pt and len(pt["ci"]) >= 2:
        out.append(("Trend per command period", png_base64(_trend_figure(a))))
    if a.fused is not None and any(np.isfinite(p.band()[0]) for p in a.fused[0].predictions):
        out.append(("Remaining useful life (fused predictor)", png_base64(_rul_figure(a))))
    return out


def legend_above_data(ax: Any, ncol: int, fontsize: float = 7) -> None:
    """The legend in a band added above the data (the y range grown upwards to make
    room), so no entry hides a trace or a level line."""
    handles, _ = ax.get_legend_handles_labels()
    if not handles:
        return
    rows = -(-len(handles) // ncol)
    share = min(0.5, 0.06 + 0.075 * rows * fontsize / 7)  # of the axes' height
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, lo + (hi - lo) / (1.0 - share))
    ax.legend(fontsize=fontsize, ncol=ncol, loc="upper center", framealpha=0.9)


def _trend_figure(a: LogAnalysis) -> Any:
    """Ci per period against the thesis' levels; the backlash indicators per period with
    the fused estimate's detection level and the backlash of the warning and failure."""
    from matplotlib.figure import Figure

    from bench.hums import rul as R
    pt = a.period_table
    te = pt["t_start_s"] + 1.0 / a.f0_hz
    fig = Figure(figsize=(11, 3.4))
    ax = fig.subplots(1, 2)
    ax[0].plot(te, judged_ci(pt["ci"], pt["ci_harmonic"]), "o", ms=3, color="C0",
               label="Ci (judged: 15 harmonics)")
    ax[0].plot(te, pt["ci"], ".", ms=3, color="0.6", label="Ci broadband (eq. 6.6)")
    for lv, c, name in ((R.THRESHOLD, "C2", "threshold"), (R.WARNING, "C1", "warning"),
                        (R.FAILURE, "C3", "failure")):
        ax[0].axhline(lv, color=c, ls="--", lw=1, label=f"{name} {lv}")
    ax[0].set(title="current fidelity per command period", xlabel="t (s)")
    legend_above_data(ax[0], ncol=3)
    ax[1].plot(te, 1e6 * pt["lost_motion_m"], ".", ms=3, label="lost motion (um)")
    if a.fused is not None:
        fr, cal, _ = a.fused
        ax[1].plot(te, fr.b_um, "-", lw=1, label="fused backlash estimate (um)")
        for b, c, ls, name in (
                (cal.warn_um, "0.4", ":", f"detection level {cal.warn_um:.2f} um"),
                (cal.backlash_at_ci(R.WARNING), "C1", "--",
                 f"warning: Ci {R.WARNING} at {cal.backlash_at_ci(R.WARNING):.0f} um"),
                (cal.fail_um, "C3", "--", f"failure: Ci {R.FAILURE} at {cal.fail_um:.0f} um")):
            ax[1].axhline(b, color=c, ls=ls, lw=1, label=name)
    ax[1].set(title="backlash indicators per period", xlabel="t (s)", ylabel="um")
    legend_above_data(ax[1], ncol=2)
    return fig


def _rul_figure(a: LogAnalysis) -> Any:
    """The fused predictor's RUL per period: median and 90 % band. A prediction without
    failure (inf: the fitted growth never reaches b_fail) is drawn at the top of the
    frame, the band clipped there alike on both bounds."""
    from matplotlib.figure import Figure
    fr = a.fused[0]
    ps = fr.predictions
    tp = np.array([p.t_pred_s for p in ps])
    med = np.array([p.rul_s for p in ps])
    lo = np.array([max(p.band()[0] - p.t_pred_s, 0.0) for p in ps])
    hi = np.array([p.band()[1] - p.t_pred_s for p in ps])
    finite = np.concatenate([v[np.isfinite(v)] for v in (med, lo, hi)])
    top = 1.15 * float(np.max(finite)) if len(finite) and np.max(finite) > 0 else 1.0
    fig = Figure(figsize=(8, 3.4))
    ax = fig.subplots()
    ax.fill_between(tp, np.minimum(lo, top), np.minimum(hi, top), color="C1", alpha=0.25,
                    lw=0, label="90 % band")
    ok = np.isfinite(med)
    ax.plot(tp, np.where(ok, med, np.nan), "C1-o", ms=3,
            label="RUL, median" if ok.any() else None)
    if not ok.all():
        ax.plot(tp[~ok], np.full((~ok).sum(), top), "v", color="C3", ms=5,
                label="median: no failure predicted")
    ax.set_title("predicted remaining useful life" + (
        "\n(at the top of the frame: no failure predicted)" if not np.isfinite(hi).all()
        else ""), fontsize=9)
    ax.set(xlabel="t (s)", ylabel="s of this manoeuvre", ylim=(0, top * 1.04))
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig


def _fmt(v: float, scale: float = 1.0, digits: int = 3) -> str:
    """`digits` significant digits; negative: -`digits` decimals (Ci: as the CLI prints)."""
    if not math.isfinite(v):
        return "-"
    return f"{v * scale:.{-digits}f}" if digits < 0 else f"{v * scale:.{digits}g}"


INDEX_HELP = [
    ("Cp", "position fidelity, int(x_N x) / int(x^2) (eq. 6.5)", "1; > 1 when the nut "
     "moves less than the model (lost motion)"),
    ("|e|", "mean |x_N - x| (eq. 6.4), um", "near 0"),
    ("Ci", "current fidelity, int(i_N i) / int(i^2) (eq. 6.6) on the command frequency and "
     "its first 15 multiples; broadband where the log has no command frequency. The verdict "
     "reads it", "1; < 1 when the motor needs more current than the model (friction, "
     "backlash impacts). Thesis levels: 0.93 threshold, 0.80 warning, 0.56 failure"),
    ("Ci broadband", "eq. 6.6 over the whole spectrum, the thesis' literal reading",
     "1 without noise; sensor noise up to 500 Hz pulls it down (about 0.9 on a healthy "
     "actuator with the bench's noise), so the thesis' levels are not read on it"),
    ("peak ratio", "max|i| / max|i_N| (eq. 6.7)", "1; very noise-sensitive"),
    ("lost motion", "encoder travel minus LVDT, forward minus backward, um",
     "near 0; about 1.4 x backlash once preload no longer takes it up"),
    ("harmonic distortion", "sqrt(sum harmonics 2-5 ^2) / fundamental of the current",
     "the nominal model's value"),
]


def _ci_reading(ix: I.Indexes) -> str:
    """Which reading `judged_ci` took (the choice is made there only)."""
    ci = judged_ci(ix.ci, ix.ci_harmonic)
    if not math.isfinite(ci):
        return "-"
    return "15 harmonics" if ci == ix.ci_harmonic else "broadband (no command frequency)"


def _index_rows(ix: I.Indexes) -> list[list[str]]:
    """The whole-log index table of one log: index, value, reading."""
    rows: list[tuple[str, float, float, int, str]] = [
        ("Cp", ix.cp, 1.0, 4, "eq. 6.5"), ("|e| (um)", ix.mean_error_m, 1e6, 3, "eq. 6.4"),
        ("Ci", judged_ci(ix.ci, ix.ci_harmonic), 1.0, -3, "judged: " + _ci_reading(ix)),
        ("Ci broadband", ix.ci, 1.0, -3, "eq. 6.6, whole spectrum"),
        ("peak ratio", ix.peak_ratio, 1.0, 3, "eq. 6.7"),
        ("lost motion (um)", ix.lost_motion_m, 1e6, -1, ""),
        ("nominal lost motion (um)", ix.nominal_lost_motion_m, 1e6, -1, ""),
        ("harmonic distortion", ix.harmonic_distortion, 1.0, 3, ""),
        ("nominal harmonic distortion", ix.nominal_harmonic_distortion, 1.0, 3, ""),
        ("friction current (A)", ix.friction_current_a, 1.0, 3, ""),
        ("nominal friction current (A)", ix.nominal_friction_current_a, 1.0, 3, "")]
    return [[k, _fmt(v, sc, dg), note] for k, v, sc, dg, note in rows]


def summary_rows(analyses: list[LogAnalysis]) -> list[dict[str, Any]]:
    """The summary table's numbers per log (the page shows them, `indexes.json` holds
    the same): Ci is `judged_ci`, the one the verdict reads."""
    return [{"log": a.name, "command": _describe(a), "duration_s": len(a.trace) * a.trace.dt,
             "ci": judged_ci(a.indexes.ci, a.indexes.ci_harmonic), "cp": a.indexes.cp,
             "lost_motion_um": a.indexes.lost_motion_m * 1e6, "verdict": a.verdict.name,
             "rul": _rul_text(a)} for a in analyses]


def render(analyses: list[LogAnalysis]) -> str:
    """The HTML text of the report (``hums_report.html.j2`` on the reports' base page)."""
    from bench.hums import rul as R
    from bench.reports import Table, anchor
    from bench.reports import render as render_page
    summary = Table(["log", "command", "duration (s)", "Ci", "Cp", "lost motion (um)",
                     "verdict", "RUL (s) [90 % band]"],
                    [[r["log"], r["command"], f"{r['duration_s']:.1f}", _fmt(r["ci"], digits=-3),
                      _fmt(r["cp"], digits=4), _fmt(r["lost_motion_um"], digits=-1), r["verdict"],
                      _rul_text(a, short=True)]
                     for r, a in zip(summary_rows(analyses), analyses, strict=True)],
                    numeric=[False, False, True, True, True, True, False, False])
    logs: list[dict[str, Any]] = []
    for a in analyses:
        ix = a.indexes
        lines = None
        if ix.harmonics_a:
            lines = Table(["current line"] + [f"{h + 1} x f0" for h in range(len(ix.harmonics_a))],
                          [["log (A)"] + [_fmt(v) for v in ix.harmonics_a],
                           ["nominal (A)"] + [_fmt(v) for v in ix.nominal_harmonics_a]])
        logs.append({"name": a.name, "anchor": "log-" + anchor(a.name),
                     "verdict": a.verdict.name,
                     "reasons": a.reasons, "missing": a.missing, "notes": a.notes,
                     "unavailable": ix.unavailable, "rul": _rul_text(a),
                     "indexes": Table(["index (whole log)", "value", "reading"],
                                      _index_rows(ix), numeric=[False, True, False]),
                     "lines": lines, "figures": _figures(a)})
    return render_page("hums_report.html.j2", title="EMA ball-screw health report",
                       nav=[("#summary", "summary"), ("#how-to-read", "how to read")]
                       + [("#" + str(g["anchor"]), str(g["name"])) for g in logs],
                       summary=summary,
                       help=Table(["index", "what it is", "healthy value"],
                                  [list(h) for h in INDEX_HELP], numeric=[False] * 3),
                       logs=logs, levels=(R.THRESHOLD, R.WARNING, R.FAILURE))


def _describe(a: LogAnalysis) -> str:
    mode = _mode(a.trace)
    kind = {MODE_POSITION: "position loop", MODE_SPEED: "speed loop (open loop)"}.get(
        mode, "idle")
    if math.isfinite(a.f0_hz):
        return f"{kind}, periodic {a.f0_hz:.3g} Hz"
    return f"{kind}, non-periodic"


def _rul_text(a: LogAnalysis, short: bool = False) -> str:
    """The RUL in words: the last prediction's median and 90 % band (s of the logged
    manoeuvre's operation), or why there is none (`short`: what comes before the
    explanation, the part before its first colon)."""
    text = _rul_words(a)
    return text.split(":")[0] if short and ":" in text else text


def _rul_words(a: LogAnalysis) -> str:
    if a.fused is None:
        return a.rul_note or "n/a"
    fr, cal, _ = a.fused
    if not fr.predictions:
        if math.isfinite(fr.t_warning_s):
            return (f"backlash detected at t = {fr.t_warning_s:.1f} s: too few periods above "
                    "the fit floor for a fit yet")
        return "no backlash detected: no RUL predicted"
    p = fr.predictions[-1]
    lo, hi = p.band()
    lo, hi = max(lo - p.t_pred_s, 0.0), hi - p.t_pred_s
    at = f"at t = {p.t_pred_s:.1f} s"
    if math.isfinite(p.rul_s):
        upper = f"{hi:.1f}" if math.isfinite(hi) else "no failure"
        return f"{p.rul_s:.1f} [{lo:.1f}, {upper}] {at}"
    b = float(np.nanmedian(fr.b_um[-3:]))
    low = (f"; 5 % of the bootstrap fits reach it within {lo:.0f} s" if math.isfinite(lo)
           else "")
    return (f"no failure predicted {at}: the fused backlash estimate ({b:.1f} um) does not "
            f"grow measurably over this log, so its trend never reaches the failure "
            f"backlash {cal.fail_um:.1f} um{low}; a RUL needs a log that spans the wear")


MIN_PERIOD_SAMPLES = 8                  # fewest a command period holds (bench.hums.periods)


def check_period(tr: Trace, name: str, period: float) -> None:
    """`--period` against the log `name` (BenchError): MIN_PERIOD_SAMPLES samples or more,
    and no longer than the log. The harmonic Ci the verdict reads and the per-period
    indexes take whole command periods and need one (`bench.hums.formulas.ci_harmonic`);
    without one Ci falls back to the broadband reading, which calls a healthy noisy log
    degraded. A log too short for a verdict is left to the report, which says so."""
    if len(tr) < 2:
        return
    dt, duration = tr.dt, len(tr) * tr.dt
    if period > duration * (1.0 + 1e-9):
        raise BenchError(f"--period {period:g} s is longer than the log {name} ("
                         f"{duration:.4g} s): the indexes read whole command periods, "
                         "and the log must hold at least one")
    if period < MIN_PERIOD_SAMPLES * dt * (1.0 - 1e-9):
        raise BenchError(f"--period {period:g} s holds fewer than {MIN_PERIOD_SAMPLES} "
                         f"samples of the log {name} (one every {dt:g} s, "
                         f"{duration:.4g} s in all): too short for a command period")


def write_report(paths: list[str], out_dir: str | Path, params: PlantParams | None = None,
                 rul: bool = True, period_s: float | None = None,
                 progress: bool = True) -> tuple[Path, list[LogAnalysis]]:
    """Analyse every log and write ``report.html`` (and ``indexes.json``) into out_dir."""
    if not paths:
        raise BenchError("give at least one log")
    from bench.bus.logs import load_trace
    from bench.core.filenames import distinct_labels
    traces = [load_trace(p) for p in paths]     # every log read and its --period checked
    if period_s is not None:                    # before the first analysis
        for p, tr in zip(paths, traces, strict=True):
            check_period(tr, p, period_s)
    analyses = [analyse(tr, label, params, rul, period_s, progress)
                for tr, label in zip(traces, distinct_labels(paths), strict=True)]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    page = out / "report.html"
    page.write_text(render(analyses))
    js = [{"log": a.name, "verdict": a.verdict.name, "reasons": a.reasons, "log_notes": a.notes,
           "bridged_samples": a.bridged,
           "fundamental_hz": a.f0_hz if math.isfinite(a.f0_hz) else None,
           "summary": json_safe(row), "indexes": json_safe(index_record(a.indexes)),
           "rul": row["rul"]} for a, row in zip(analyses, summary_rows(analyses), strict=True)]
    (out / "indexes.json").write_text(json.dumps(js, indent=2))
    return page, analyses


