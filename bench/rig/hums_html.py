"""The HTML page of `bench hums report` on a rig's log (`bench.rig.hums`): summary, what
each verdict was judged against, the sections with their indexes or the reason they are
not available, and figures (matplotlib `Figure` API, embedded as base64 PNG so the HTML
file is all there is)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.core.jsonsafe import json_safe
from bench.reports import (
    Block,
    Bullets,
    Document,
    Figure,
    Heading,
    Paragraph,
    Table,
    badge,
    marked,
    png_base64,
    render_document,
    strong,
)
from bench.rig import fallback as FB
from bench.rig import hums as H
from bench.rig.baseline import residuals
from bench.rig.cycles import phases

MF_LABELS = [("position_error_mean_mm", "position error, mean (mm)"),
             ("position_error_peak_mm", "position error, peak |e| (mm)"),
             ("position_error_rms_mm", "position error, RMS (mm)"),
             ("current_rms_a", "current, RMS (A)"), ("current_peak_a", "current, peak |i| (A)")]
MODEL_LABELS = {"cp": "Cp (eq. 6.5)", "mean_error_m": "|e|, mean position error (mm, eq. 6.4)",
                "ci": "Ci (eq. 6.6)", "peak_ratio": "peak-current ratio (eq. 6.7)"}


def _fmt(v: Any, digits: int = 4) -> str:
    return f"{v:.{digits}g}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def signals_figure(a: H.RigAnalysis) -> str:
    """Position, position error and current against time: the log, and the calibrated
    model where there is one."""
    from matplotlib.figure import Figure
    tr = a.trace
    t = tr.t
    fig = Figure(figsize=(11, 6.6))
    ax = fig.subplots(3, 1, sharex=True)
    sp = 1e3 * np.asarray(tr["setpoint_position_m"], float)
    ax[0].plot(t, sp, "C7--", lw=1, label="set-point")
    if "position_m" in tr:
        x = 1e3 * np.asarray(tr["position_m"], float)
        ax[0].plot(t, x, "k", lw=1.2, label="log")
        ax[1].plot(t, sp - x, "k", lw=1, label="log")
    if "position_m" in a.sim:
        xm = 1e3 * a.sim["position_m"]
        ax[0].plot(t, xm, "C0:", lw=1.5, label="calibrated model")
        ax[1].plot(t, sp - xm, "C0", lw=1, label="calibrated model")
    if "current_a" in tr:
        ax[2].plot(t, tr["current_a"], "k", lw=1, label="log")
    if "current_a" in a.sim:
        ax[2].plot(t, a.sim["current_a"], "C0", lw=1, label="calibrated model")
    for axis, (title, unit) in zip(ax, (("nut position", "mm"),
                                        ("position error (set-point - position)", "mm"),
                                        ("motor current", "A")), strict=True):
        axis.set_title(title, fontsize=10)
        axis.set_ylabel(unit)
        axis.grid(alpha=0.3)
        if axis.lines:
            axis.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax[2].set_xlabel("t (s)")
    fig.subplots_adjust(left=0.07, right=0.84, bottom=0.08, top=0.95, hspace=0.35)
    return png_base64(fig, tight=False)


def worst_text(b: dict[str, Any]) -> str:
    """Which cycle the baseline figure shows, and why (`fallback.worst_cycle`)."""
    v = b["verdicts"][b["worst"]]
    judged = [x for x in b["verdicts"] if x["judged"]]
    if len(judged) == 1:
        return f"{v['cycle']} (the only cycle judged)"
    if not v["flagged"]:
        return (f"{v['cycle']}: no cycle flagged; the one closest to a threshold (largest "
                f"score / threshold {v['largest_ratio']:.2f})")
    return (f"{v['cycle']}: the most flagged of {len(judged)} cycles judged "
            f"({v['features_above']} feature(s) above threshold, largest score / threshold "
            f"{v['largest_ratio']:.2f})")


def baseline_figure(a: H.RigAnalysis) -> str | None:
    """The log's most flagged cycle (`fallback.worst_cycle`) against the baseline: current
    with the baseline's mean and +-2 spread per aligned sample, and the standardised
    residual against the measured position in each stroke with the located effect
    marked."""
    from matplotlib.figure import Figure

    from bench.rig.fallback import log_cycles
    b, base = a.baseline, a.base_obj
    if b is None or base is None or b.get("worst") is None:
        return None
    v = b["verdicts"][b["worst"]]
    cyc = log_cycles(a.trace, a.name)[b["worst"]]
    cyc.load = v["baseline_load"]
    lb = base.for_load(cyc.load)
    fig = Figure(figsize=(11, 6.2))
    ax = fig.subplots(2, 1)
    ax[0].plot(cyc.t_s, cyc.current_a, "k", lw=1.2, label="log")
    first = True
    for seg in phases(cyc.setpoint_mm):
        ps = lb.phases.get(seg.name)
        if ps is None:
            continue
        m = min(len(seg), len(ps))
        tt = cyc.t_s[seg.start:seg.start + m]
        mu, sd = ps.mean["current_a"][:m], ps.std["current_a"][:m]
        ax[0].plot(tt, mu, "C2", lw=1, label="baseline mean" if first else None)
        ax[0].fill_between(tt, mu - 2 * sd, mu + 2 * sd, color="C2", alpha=0.25,
                           label="baseline +-2 sd" if first else None)
        first = False
    ax[0].set(title=f"motor current against the healthy baseline ({cyc.label})",
              xlabel="t in the cycle (s)", ylabel="A")
    ax[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    res = residuals(lb, cyc, "current_a")
    for stroke, color in (("out", "C0"), ("in", "C3")):
        if stroke in res:
            z, pos = res[stroke]
            ax[1].plot(pos, z, color, lw=1, label=f"{stroke}-stroke")
    if v.get("location_mm") is not None:
        ax[1].axvline(v["location_mm"], color="C1", ls="--", lw=1.2,
                      label=f"located effect {v['location_mm']:.1f} mm")
    ax[1].axhline(0, color="k", lw=0.5)
    ax[1].set(title="current residual against the baseline, standardised by its spread",
              xlabel="measured position (mm)", ylabel="residual (baseline sd)")
    ax[1].grid(alpha=0.3)
    ax[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    # both panels the same width, their legends to the right of the data
    fig.subplots_adjust(left=0.07, right=0.82, bottom=0.09, top=0.94, hspace=0.45)
    return png_base64(fig, tight=False)


def _model_free(a: H.RigAnalysis) -> list[Block]:
    dirs = [d for d in ("extend", "retract", "dwell", "all") if d in a.model_free]
    if not dirs:
        return []
    rows = [[label] + [_fmt(a.model_free[d].get(key, math.nan)) for d in dirs]
            for key, label in MF_LABELS if any(key in a.model_free[d] for d in dirs)]
    return [Heading("Model-free indexes (no model, no baseline)", 3),
            Table(["index"] + [f"{d} ({int(a.model_free[d]['samples'])} samples)"
                               for d in dirs], rows)]


def _model(a: H.RigAnalysis) -> list[Block]:
    m = a.model
    if m is None:
        return []
    parts: list[Block] = [Heading(f"Against the calibrated model ({m['calibration']})", 3)]
    if not m["reaches_noise_floor"]:
        how = ("its indexes are shown for information; the verdict comes from the healthy "
               "baseline" if a.baseline is not None and a.baseline["judged"] else
               "the verdict is judged against it nonetheless (asked for, or no healthy "
               "baseline to judge against)")
        parts.append(Paragraph(f"This model does not reach the noise floor on the "
                               f"calibration's healthy logs (worst x{m['healthy_ratio']:.3g}):"
                               f" {how}."))
    parts.append(Table(["index", "value"], [
        [MODEL_LABELS.get(k, k), _fmt(v * (1e3 if k == "mean_error_m" else 1.0),
                                      6 if k == "cp" else 4)] for k, v in m["indexes"].items()]))
    if a.gap is not None:                   # the gap's table above has the RMS ratios
        return parts
    parts.append(Table(["signal", "RMS / noise floor", "threshold", "noise floor"], [
        [s, _fmt(r, 3), _fmt(m["threshold"][s], 3), _fmt(m["noise_floor"][s], 3)]
        for s, r in m["rms_ratio"].items()]))
    return parts


def _baseline(a: H.RigAnalysis) -> list[Block]:
    b = a.baseline
    if b is None:
        return []
    parts: list[Block] = [Heading("Against the healthy baseline", 3), Paragraph(b["baseline"])]
    if b["verdicts"]:
        rows = []
        for v in b["verdicts"]:
            at = (a.base_obj.load_text(v["baseline_load"]) if v["judged"] and a.base_obj
                  else "-")
            flag = ("yes" if v["flagged"] else "no") if v["judged"] else "not judged"
            rows.append([v["cycle"], at, flag, v["verdict"], "; ".join(v["reasons"])])
        parts.append(Table(["cycle", "baseline load", "flagged", "effect",
                            "features against their thresholds"], rows, numeric=[False] * 5))
    parts += [Paragraph(n, role="note") for n in b["notes"]]
    rows = b["phase_indexes"]
    if rows:
        parts.append(Paragraph("Phase indexes (mean over the log's cycles) against the "
                               "baseline's mean and spread (information; the verdict rests on "
                               "the features above):"))
        parts.append(Table(["load", "phase", "index", "log", "baseline mean", "baseline sd",
                            "z"], [
            [f"{r['load']:g}", r["phase"], r["index"], _fmt(r["value"]),
             _fmt(r["baseline_mean"]), _fmt(r["baseline_sd"], 3),
             marked(_fmt(r["z"], 3)) if r["z"] is not None and abs(r["z"]) > 3 else
             _fmt(r["z"], 3)] for r in rows],
            numeric=[True, False, False, True, True, True, True]))
    return parts


GAP_SHARES = ("start_stop", "cruise", "dwell", "extend", "retract")


def _gap(a: H.RigAnalysis) -> list[Block]:
    """`bench gap`'s diagnosis against the calibrated model (`bench.rig.riggap`): per
    signal the RMS against its threshold and where its excess lies, the candidates
    ranked, the verdict."""
    g = a.gap
    if g is None:
        return []
    from bench.rig.riggap import judged_text
    loc = g["localisation"]
    floor = (a.model or {}).get("noise_floor") or {}
    rows = []
    for s, r in g["rms_ratio"].items():
        shares = {**loc["regimes"][s], **loc["direction"][s]}
        rows.append([s, _fmt(floor.get(s, math.nan), 3), _fmt(r, 3),
                     _fmt(g["threshold"][s], 3)] + [f"{100 * shares[k]:.0f} %"
                                                    for k in GAP_SHARES])
    parts: list[Block] = [
        Heading(f"Gap against the calibrated model: {g['verdict']}", 3),
        Paragraph(f"{judged_text(g)}."),
        Paragraph(f"{g['baseline']}; significant when a signal's RMS exceeds its threshold "
                  "(the larger of 2 and the worst ratio the calibration's held-out healthy "
                  "logs left)."),
        Table(["signal", "noise floor", "RMS / noise floor", "threshold", "start/stop",
               "cruise", "dwell", "extend", "retract"], rows),
        Paragraph("Shares of each signal's excess residual energy (above its floor) by "
                  "regime and by direction.")]
    if g["ranking"]:
        parts.append(Table(["rank", "candidate effect", "dBIC", "RMS / floor after",
                            "fitted values"], [
            [str(i), f"{r['effect']}: {r['doc']}", f"{r['delta_bic']:.1f}",
             _fmt(r["rms_ratio_after"], 3), "; ".join(f"{k} = {v:.4g}"
                                                       for k, v in r["values"].items())]
            for i, r in enumerate(g["ranking"], start=1)],
            numeric=[True, False, True, True, False]))
        parts.append(Paragraph("A candidate is named when it lowers the BIC by more than 10 "
                               "and the gap is significant."))
    parts += [Paragraph(f"{eff}: {why}") for eff, why in g.get("not_available", {}).items()]
    parts.append(Figure("", data=gap_figure(g), alt="gap by nut position"))
    return parts


def gap_figure(g: dict[str, Any]) -> str:
    """Each signal's share of its excess residual energy per nut-position bin."""
    from matplotlib.figure import Figure
    pos = g["localisation"]["position_mm"]
    fig = Figure(figsize=(11, 2.8))
    ax = fig.subplots()
    width = 0.8 / max(len(pos), 1)
    for k, (s, shares) in enumerate(pos.items()):
        x = np.arange(len(shares)) + (k - (len(pos) - 1) / 2) * width
        ax.bar(x, [100 * v for v in shares.values()], width, label=s)
        ax.set_xticks(np.arange(len(shares)), list(shares), fontsize=8)
    ax.set(title="where along the stroke the excess residual lies",
           xlabel="nut position (mm)", ylabel="share of the excess (%)")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    return png_base64(fig)

def _log(a: H.RigAnalysis) -> list[Block]:
    parts: list[Block] = [Heading(a.name), Paragraph(badge(a.verdict.name)),
                          Paragraph("Judged against: " + a.reference, role="ref"),
                          Bullets(list(a.reasons))]
    parts += _gap(a) + _model_free(a) + _model(a) + _baseline(a)
    na = {k: v for k, v in a.sections.items() if v}
    if na:
        parts += [Heading("Not available on this log", 3),
                  Bullets([strong(k) + ": " + v for k, v in na.items()])]
    parts += [Heading("Signals" + (" against the calibrated model" if a.sim else ""), 3),
              Figure("", data=signals_figure(a), alt="signals")]
    png = baseline_figure(a)
    if png:
        assert a.baseline is not None
        parts += [Heading("The most flagged cycle against the healthy baseline", 3),
                  Paragraph(worst_text(a.baseline)), Figure("", data=png, alt="baseline")]
    return parts


INTRO = ("These logs come from an actuator the bench did not simulate. Each is compared "
         "with what was given: a calibration of its generic model (`bench calibrate "
         "--actuator`), a healthy baseline built from its own healthy runs, or neither "
         "(then only indexes that need no model). What a log cannot support is listed as not "
         "available, with the reason.")
GAP_INTRO = ("`bench gap` on a log of an actuator the bench did not simulate: the "
             "log against the calibrated generic model (`bench calibrate --actuator`), the "
             "residual localised and the candidate effects ranked, or, when "
             "that model does not reach the noise floor on healthy logs, against the healthy "
             "baseline built from the actuator's own healthy runs. The same page as "
             "`bench hums report`, with the gap's diagnosis added.")
LEVELS_NOTE = ("Levels: HEALTHY within the reference (the calibrated model's healthy "
               "threshold, or every feature within the baseline's thresholds); DEGRADED "
               "outside it; UNKNOWN without a reference. Baseline thresholds come from "
               "healthy calibration runs only (docs/real-data.md).")


def summary_record(a: H.RigAnalysis) -> dict[str, Any]:
    """The summary row of `a` (the page's and ``indexes.json``'s ``summary``)."""
    dur = len(a.trace) * a.trace.dt if len(a.trace) > 1 else 0.0
    return {"log": a.name, "samples": len(a.trace), "duration_s": dur,
            "verdict": a.verdict.name, "judged_against": a.reference}


def summary_table(analyses: list[H.RigAnalysis]) -> Table:
    """One row per log: samples, duration, verdict, what it was judged against."""
    rows = [[r["log"], str(r["samples"]), f"{r['duration_s']:.1f}", badge(r["verdict"]),
             r["judged_against"]] for r in map(summary_record, analyses)]
    return Table(["log", "samples", "duration (s)", "verdict", "judged against"], rows,
                 numeric=[False, True, True, False, False], role="summary")


def render(analyses: list[H.RigAnalysis], title: str = "Actuator health report",
           intro: str = INTRO) -> str:
    """The HTML text of the report (`intro`: text, `code` spans between backticks)."""
    doc = Document()
    for a in analyses:
        doc.add(*_log(a))
    summary = Document([Paragraph(intro), Heading("Summary"), summary_table(analyses)])
    return render_document(doc, title=title, summary=summary,
                           footer=Document([Paragraph(LEVELS_NOTE, role="note")]),
                           nav=[("#summary", "summary")] + [("#" + h.anchor, h.text)
                                                           for h in doc.headings()])


def write_rig_report(paths: list[str], out_dir: str | Path, nominal: str | None = None,
                     baseline: str | None = None, against: str = "auto"
                     ) -> tuple[Path, list[H.RigAnalysis]]:
    """Analyse every log against the references given and write ``report.html``,
    ``indexes.json`` and ``summary.txt`` into out_dir."""
    if not paths:
        raise BenchError("give at least one log")
    cal = H.calibration_file(nominal) if nominal is not None else None
    ref = FB.choose(cal, nominal, baseline, against)
    from bench.bus.logs import load_trace
    from bench.core.filenames import distinct_labels
    analyses = [H.analyse_rig(load_trace(p), label, ref)
                for p, label in zip(paths, distinct_labels(paths), strict=True)]
    return write_files(analyses, out_dir), analyses


def write_files(analyses: list[H.RigAnalysis], out_dir: str | Path,
                page_name: str = "report.html", title: str = "Actuator health report",
                intro: str = INTRO) -> Path:
    """Write the page (`page_name`), ``indexes.json`` and ``summary.txt`` of `analyses`
    into out_dir; the page's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    page = out / page_name
    page.write_text(render(analyses, title, intro))
    (out / "indexes.json").write_text(json.dumps(
        [json_safe({**a.to_json(), "summary": summary_record(a)}) for a in analyses],
        indent=1, default=str))
    (out / "summary.txt").write_text("\n\n".join(H.summary_text(a) for a in analyses) + "\n")
    return page


def write_gap_report(trace: Any, name: str, ref: FB.Reference, out_dir: str | Path,
                     gap: dict[str, Any] | None = None,
                     assessed: dict[str, Any] | None = None) -> Path:
    """`bench gap --report DIR` on a rig's log: the report page of `bench hums report`
    (`analyse_rig` against the same reference) with the gap's diagnosis against the
    calibrated model (`gap`, `bench.rig.riggap.diagnose_rig`) or the baseline's
    (`assessed`, `fallback.assess`) it already made, as ``index.html``."""
    a = H.analyse_rig(trace, name, ref, assessed)
    a.gap = gap
    return write_files([a], out_dir, "index.html", "Sim-to-real gap: " + name, GAP_INTRO)
