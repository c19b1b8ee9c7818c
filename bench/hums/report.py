"""`bench hums report LOG...`: a self-contained HTML health report of one or more logs.

A log is a candump ``.log`` decoded through the DBC (`bench.bus.logs.trace_from_log`,
when that module is installed) or a trace table (``.npz``, ``.csv``, ``.parquet``,
`bench.trace.Trace.load`). The report compares each log with the monitoring model
driven by the log's own set-points and gives, for a reader who never ran the bench:
what was run, the indexes with their healthy ranges, a verdict, the per-period trend
and, for long periodic logs, the fused backlash estimate and the RUL with its band.
Figures are embedded as base64 PNG, so the HTML file is all there is.
"""

from __future__ import annotations

import base64
import hashlib
import html
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums import indexes as I
from bench.hums import monitor as M
from bench.hums.verdict import LEVELS, UNKNOWN, judge  # noqa: F401  (LEVELS, UNKNOWN: re-exported)
from bench.jsonsafe import json_safe
from bench.trace import MEASURED, MODE_POSITION, MODE_SPEED, Trace
from plant_rt.params import PlantParams

MIN_PERIODS_FOR_TREND = 6


def load_log(path: str | Path) -> Trace:
    """A Trace from a candump log (through the DBC) or a trace table."""
    from bench.bus.logs import load_trace
    return load_trace(path)


def command_frequency(trace: Trace) -> float:
    """The command frequency (Hz): the trace's metadata, else the strongest line of the
    set-point spectrum (NaN for a non-periodic command such as a step)."""
    v = trace.meta.get("fundamental_hz")
    try:
        f0 = float(v) if v is not None else math.nan
    except (TypeError, ValueError):
        f0 = math.nan
    if math.isfinite(f0) and f0 > 0:
        return f0
    mode = _mode(trace)
    col = "setpoint_position_m" if mode == MODE_POSITION else "setpoint_speed_rad_s"
    if col not in trace or len(trace) < 64:
        return math.nan
    y = np.nan_to_num(trace[col])
    if np.ptp(y) == 0:
        return math.nan
    f, a = I.amplitude_spectrum(y, trace.dt)
    k = int(np.argmax(a[1:]) + 1)
    # a periodic command puts most of its variance in that line
    if a[k] ** 2 / 2 < 0.5 * np.var(y) or f[k] * len(trace) * trace.dt < 2:
        return math.nan
    # refine to the nearest whole number of samples per period
    per = round(1.0 / (f[k] * trace.dt))
    return 1.0 / (per * trace.dt)


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
    verdict: str
    reasons: list[str]
    period_table: dict[str, np.ndarray] = field(default_factory=dict)
    fused: Any = None
    missing: list[str] = field(default_factory=list)
    bridged: dict[str, int] = field(default_factory=dict)   # signal -> samples bridged
    notes: list[str] = field(default_factory=list)          # what the log lost / repeated


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
    f0 = 1.0 / period_s if period_s else command_frequency(meas)
    meas.meta["fundamental_hz"] = f0
    ix = I.compare(meas, nom, f0_hz=f0 if math.isfinite(f0) else None, need=())
    I.mark_unavailable(ix, blocked, M.NOMINAL_DRIVE)
    out = LogAnalysis(name, meas, nom, f0, ix, "", [], missing=missing, bridged=bridged,
                      notes=notes)
    n_periods = int(len(meas) * meas.dt * f0) if math.isfinite(f0) else 0
    trend_blocked = set(blocked) & {"current_a", "position_m", *M.NOMINAL_DRIVE}
    if trend_blocked:
        notes.append("no trend or RUL: " + "; ".join(blocked[c] for c in sorted(trend_blocked)))
    elif have_i and have_x and n_periods >= 1:
        rows = list(I.period_indexes(meas, nom, 1.0 / f0, kin=None))
        out.period_table = I.as_table(rows)
    if rul and n_periods >= MIN_PERIODS_FOR_TREND and out.period_table:
        from bench.hums import fusion as R
        cal = cached_calibration(M.nominal_plant(params), kp, progress)
        t_end = out.period_table["t_start_s"] + 1.0 / f0
        out.fused = (R.FusedPredictor(cal).run(t_end, out.period_table), cal, t_end)
    out.verdict, out.reasons = verdict(out)
    return out


def _log_notes(meta: dict[str, Any]) -> list[str]:
    """What the decoder found wrong with the log (lost SYNCs, missing frames, ...)."""
    try:
        from bench.bus.logs import integrity
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
    out = LogAnalysis(name, meas, nom, math.nan, ix, "", [], missing=missing, notes=notes)
    out.verdict, out.reasons = verdict(out)
    return out


def verdict(a: LogAnalysis) -> tuple[str, list[str]]:
    """The log's verdict and its reasons (`bench.hums.verdict.judge` on the log's indexes,
    its most frequent mode and its fused backlash estimate)."""
    return judge(a.indexes, _mode(a.trace), a.fused)


# --- rendering -----------------------------------------------------------------------------

def _png(fig: Any) -> str:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _figures(a: LogAnalysis) -> list[tuple[str, str]]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = []
    tr, nm = a.trace, a.nominal
    t = tr.t
    n = len(t)
    show = slice(0, min(n, int(4.0 / max(tr.dt, 1e-9)))) if n * tr.dt > 8 else slice(0, n)
    fig, ax = plt.subplots(1, 2, figsize=(11, 3.4))
    if "position_m" in tr:
        ax[0].plot(t[show], 1e3 * tr["position_m"][show], "k", lw=1.5, label="log (LVDT)")
        ax[0].plot(t[show], 1e3 * nm["position_m"][show], "C0--", label="nominal model")
    ax[0].set(title="nut position", xlabel="t (s)", ylabel="mm")
    ax[0].legend(fontsize=8)
    if "current_a" in tr:
        ax[1].plot(t[show], tr["current_a"][show], "k", lw=1, label="log")
        ax[1].plot(t[show], nm["current_a"][show], "C0--", label="nominal model")
    ax[1].set(title="motor current", xlabel="t (s)", ylabel="A")
    ax[1].legend(fontsize=8)
    out.append(("Measured signals against the nominal model"
                + (" (first 4 s)" if show.stop < n else ""), _png(fig)))
    if "current_a" in tr and np.isfinite(tr["current_a"]).all() and n >= 64:
        fig, ax = plt.subplots(figsize=(6, 3.2))
        f, amp = I.amplitude_spectrum(tr["current_a"], tr.dt)
        fn, an = I.amplitude_spectrum(nm["current_a"], tr.dt)
        ax.plot(fn, an, "C0", lw=2, label="nominal model")
        ax.plot(f, amp, "k", lw=1, label="log")
        top = 20 * a.f0_hz if math.isfinite(a.f0_hz) else 50.0
        ax.set(xlim=(0, top), title="current spectrum (Hann, amplitude)", xlabel="Hz",
               ylabel="A")
        ax.legend(fontsize=8)
        out.append(("Current spectrum (eq. 6.3)", _png(fig)))
    pt = a.period_table
    if pt and len(pt["ci"]) >= 2:
        te = pt["t_start_s"] + 1.0 / a.f0_hz
        fig, ax = plt.subplots(1, 2, figsize=(11, 3.4))
        ax[0].plot(te, pt["ci"], ".", ms=3, label="Ci")
        ax[0].plot(te, pt["ci_harmonic"], ".", ms=3, label="Ci, 15 harmonics")
        for lv, c in ((0.93, "C2"), (0.80, "C1"), (0.56, "C3")):
            ax[0].axhline(lv, color=c, ls="--", lw=1)
        ax[0].set(title="current fidelity per command period", xlabel="t (s)")
        ax[0].legend(fontsize=8)
        ax[1].plot(te, 1e6 * pt["lost_motion_m"], ".", ms=3, label="lost motion (um)")
        if a.fused is not None:
            fr, cal, _ = a.fused
            ax[1].plot(te, fr.b_um, "-", lw=1, label="fused backlash estimate (um)")
            ax[1].axhline(cal.warn_um, color="C1", ls="--", lw=1, label="warning level")
        ax[1].set(title="backlash indicators per period", xlabel="t (s)")
        ax[1].legend(fontsize=8)
        out.append(("Trend per command period", _png(fig)))
    if a.fused is not None and a.fused[0].predictions:
        fr = a.fused[0]
        ps = fr.predictions
        tp = np.array([p.t_pred_s for p in ps])
        fig, ax = plt.subplots(figsize=(6, 3.2))
        ax.plot(tp, [p.rul_s for p in ps], "C1", label="RUL, median")
        ax.fill_between(tp, [p.band()[0] - p.t_pred_s for p in ps],
                        [min(p.band()[1] - p.t_pred_s, 1e3) for p in ps], color="C1",
                        alpha=0.25, label="90 % band")
        ax.set(title="predicted remaining useful life", xlabel="t (s)", ylabel="s",
               ylim=(0, None))
        ax.legend(fontsize=8)
        out.append(("Remaining useful life (fused predictor)", _png(fig)))
    return out


def _fmt(v: float, scale: float = 1.0, digits: int = 3) -> str:
    return "-" if not math.isfinite(v) else f"{v * scale:.{digits}g}"


INDEX_HELP = [
    ("Cp", "position fidelity, int(x_N x) / int(x^2) (eq. 6.5)", "1; > 1 when the nut "
     "moves less than the model (lost motion)"),
    ("|e|", "mean |x_N - x| (eq. 6.4), um", "near 0"),
    ("Ci", "current fidelity, int(i_N i) / int(i^2) (eq. 6.6)", "1; < 1 when the motor "
     "needs more current than the model (friction, backlash impacts). Thesis levels: 0.93 "
     "threshold, 0.80 warning, 0.56 failure"),
    ("Ci (15 harmonics)", "Ci on the command frequency and its first 15 multiples",
     "as Ci, but broadband sensor noise does not pull it down"),
    ("peak ratio", "max|i| / max|i_N| (eq. 6.7)", "1; very noise-sensitive"),
    ("lost motion", "encoder travel minus LVDT, forward minus backward, um",
     "near 0; about 1.4 x backlash once preload no longer takes it up"),
    ("harmonic distortion", "sqrt(sum harmonics 2-5 ^2) / fundamental of the current",
     "the nominal model's value"),
]


def render(analyses: list[LogAnalysis]) -> str:
    """The HTML text of the report."""
    from bench.hums import rul as R
    e = html.escape
    parts = ["<!doctype html><html><head><meta charset='utf-8'>",
             "<title>EMA ball-screw HUMS report</title><style>",
             "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}",
             "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #bbb;"
             "padding:3px 8px;text-align:right}th{background:#eee}td.l{text-align:left}",
             ".v{display:inline-block;padding:4px 12px;border-radius:4px;color:#fff;"
             "font-weight:bold}.HEALTHY{background:#2a7}.DEGRADED{background:#c90}"
             ".WARNING{background:#d60}.FAILURE{background:#c22}.UNKNOWN{background:#777}"
             "img{max-width:100%}",
             "</style></head><body>",
             "<h1>EMA ball-screw health report</h1>",
             "<p>Each log is compared with the <b>monitoring model</b>: the nominal "
             "actuator of thesis section 6.1 (same motor, drive and controller, rigid "
             "screw, nominal friction) driven by the same set-points as the log. The "
             "indexes measure how far the logged actuator is from that nominal one.</p>"]
    parts.append("<h2>Summary</h2><table><tr><th>log</th><th>command</th><th>duration (s)"
                 "</th><th>Ci</th><th>Cp</th><th>lost motion (um)</th><th>verdict</th>"
                 "<th>RUL (s) [90 % band]</th></tr>")
    for a in analyses:
        parts.append(f"<tr><td class='l'>{e(a.name)}</td><td class='l'>{e(_describe(a))}"
                     f"</td><td>{len(a.trace) * a.trace.dt:.1f}</td>"
                     f"<td>{_fmt(a.indexes.ci)}</td><td>{_fmt(a.indexes.cp, digits=4)}</td>"
                     f"<td>{_fmt(a.indexes.lost_motion_m, 1e6)}</td>"
                     f"<td><span class='v {a.verdict}'>{a.verdict}</span></td>"
                     f"<td>{e(_rul_text(a))}</td></tr>")
    parts.append("</table>")
    parts.append("<h2>How to read the indexes</h2><table><tr><th>index</th><th>what it is"
                 "</th><th>healthy value</th></tr>")
    for k, what, ok in INDEX_HELP:
        parts.append(f"<tr><td class='l'>{e(k)}</td><td class='l'>{e(what)}</td>"
                     f"<td class='l'>{e(ok)}</td></tr>")
    parts.append("</table>")
    for a in analyses:
        ix = a.indexes
        parts.append(f"<h2>{e(a.name)}</h2><p><span class='v {a.verdict}'>{a.verdict}"
                     f"</span></p><ul>" + "".join(f"<li>{e(r)}</li>" for r in a.reasons)
                     + "</ul>")
        if a.missing:
            parts.append(f"<p>Signals missing from this log: {e(', '.join(a.missing))}; "
                         "the indexes that need them are left out.</p>")
        if a.notes:
            parts.append("<p>The log: " + e("; ".join(a.notes)) + ".</p>")
        if ix.unavailable:
            parts.append("<p>Indexes not available:</p><ul>" + "".join(
                f"<li>{e(k)}: {e(v)}</li>" for k, v in ix.unavailable.items()) + "</ul>")
        rows = [("Cp", ix.cp, 1.0, 4), ("|e| (um)", ix.mean_error_m, 1e6, 3),
                ("Ci", ix.ci, 1.0, 3), ("Ci (15 harmonics)", ix.ci_harmonic, 1.0, 3),
                ("peak ratio", ix.peak_ratio, 1.0, 3),
                ("lost motion (um)", ix.lost_motion_m, 1e6, 3),
                ("nominal lost motion (um)", ix.nominal_lost_motion_m, 1e6, 2),
                ("harmonic distortion", ix.harmonic_distortion, 1.0, 3),
                ("nominal harmonic distortion", ix.nominal_harmonic_distortion, 1.0, 3),
                ("friction current (A)", ix.friction_current_a, 1.0, 3),
                ("nominal friction current (A)", ix.nominal_friction_current_a, 1.0, 3)]
        parts.append("<table><tr><th>index (whole log)</th><th>value</th></tr>")
        for k, v, sc, dg in rows:
            parts.append(f"<tr><td class='l'>{e(k)}</td><td>{_fmt(v, sc, dg)}</td></tr>")
        parts.append("</table>")
        if ix.harmonics_a:
            parts.append("<table><tr><th>current line</th>" + "".join(
                f"<th>{h + 1} x f0</th>" for h in range(len(ix.harmonics_a)))
                + "</tr><tr><td class='l'>log (A)</td>" + "".join(
                f"<td>{_fmt(v)}</td>" for v in ix.harmonics_a) + "</tr><tr><td class='l'>"
                "nominal (A)</td>" + "".join(f"<td>{_fmt(v)}</td>"
                                             for v in ix.nominal_harmonics_a) + "</tr></table>")
        for title, png in _figures(a):
            parts.append(f"<h3>{e(title)}</h3><img alt='{e(title)}' "
                         f"src='data:image/png;base64,{png}'>")
    parts.append(f"<p><small>Levels: Ci threshold {R.THRESHOLD}, warning {R.WARNING}, "
                 f"failure {R.FAILURE} (thesis section 6.5). The RUL is the fused "
                 "predictor's (docs/hums.md): exponential growth of the fused backlash "
                 "estimate to the backlash at which Ci reaches 0.56, band from a bootstrap "
                 "of the fit.</small></p></body></html>")
    return "\n".join(parts)


def _describe(a: LogAnalysis) -> str:
    mode = _mode(a.trace)
    kind = {MODE_POSITION: "position loop", MODE_SPEED: "speed loop (open loop)"}.get(
        mode, "idle")
    if math.isfinite(a.f0_hz):
        return f"{kind}, periodic {a.f0_hz:.3g} Hz"
    return f"{kind}, non-periodic"


def _rul_text(a: LogAnalysis) -> str:
    if a.fused is None:
        return "n/a (needs a periodic log of >= 6 command periods)"
    fr = a.fused[0]
    if not fr.predictions:
        if math.isfinite(fr.t_warning_s):
            return "warning, too few points for a fit yet"
        return "no warning: no RUL predicted"
    p = fr.predictions[-1]
    lo, hi = p.band()
    return (f"{p.rul_s:.1f} [{max(lo - p.t_pred_s, 0):.1f}, "
            f"{hi - p.t_pred_s:.1f}] at t = {p.t_pred_s:.1f} s")


def write_report(paths: list[str], out_dir: str | Path, params: PlantParams | None = None,
                 rul: bool = True, period_s: float | None = None,
                 progress: bool = True) -> tuple[Path, list[LogAnalysis]]:
    """Analyse every log and write ``report.html`` (and ``indexes.json``) into out_dir."""
    if not paths:
        raise BenchError("give at least one log")
    from bench.filenames import distinct_labels
    analyses = []
    for p, label in zip(paths, distinct_labels(paths), strict=True):
        tr = load_log(p)
        analyses.append(analyse(tr, label, params, rul, period_s, progress))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    page = out / "report.html"
    page.write_text(render(analyses))
    js = [{"log": a.name, "verdict": a.verdict, "reasons": a.reasons, "log_notes": a.notes,
           "bridged_samples": a.bridged,
           "fundamental_hz": a.f0_hz if math.isfinite(a.f0_hz) else None,
           "indexes": json_safe(a.indexes.to_json()), "rul": _rul_text(a)} for a in analyses]
    (out / "indexes.json").write_text(json.dumps(js, indent=2))
    return page, analyses


