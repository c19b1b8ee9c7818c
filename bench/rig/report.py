"""The study's figures (matplotlib `Figure` API) and its report, one `bench.reports`
Document written as markdown (report.md) and as the styled page (report.html, from the
reports' base template): the current residual against position with the located effect,
the detection rate per stage and load beside the plain z-score's, the tables of
docs/real-data.md."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from bench.reports import Block, Document, Heading, Paragraph, Table
from bench.reports import Figure as PageFigure
from bench.rig.report_goals import ci, goal_blocks, pct
from bench.rig.study import Study, mean_profile


def residual_figure(study: Study, path: Path) -> Path:
    """Per load: the mean current residual (z) against measured position, out- and
    in-stroke, of the held-out healthy runs and of the first, middle and last fault
    stage, with each stage's located position (median) marked."""
    from matplotlib.figure import Figure
    loads = study.loads
    fig = Figure(figsize=(12, 3.2 * len(loads) + 0.6), layout="constrained")
    axes = fig.subplots(len(loads), 2, squeeze=False)
    faults = study.fault_conditions
    picked = sorted({0, len(faults) // 2, len(faults) - 1}) if faults else []
    conds = [study.healthy_condition] + [faults[i] for i in picked]
    cmap = __import__("matplotlib").colormaps["viridis"]
    for i, load in enumerate(loads):
        row = study.summary["loads"][f"{load:g}"]
        for j, stroke in enumerate(("out", "in")):
            ax = axes[i][j]
            for k, cond in enumerate(conds):
                rs = study.results.get(cond, {}).get(load, [])
                z, pos = mean_profile(rs, stroke)
                if not len(z):
                    continue
                healthy = cond == study.healthy_condition
                color = "k" if healthy else cmap(k / max(1, len(conds) - 1))
                ax.plot(pos, z + 0 * k, color=color, lw=1.6 if healthy else 0.9,
                        label=f"{cond} (held-out runs)" if healthy else cond)
                where = row["stages"].get(cond, {}).get("position_mm", float("nan"))
                if not healthy and math.isfinite(where):
                    ax.axvline(where, color=color, ls=":", lw=0.8)
            _stroke_panel(ax, f"load {study.baseline.load_text(load)}, {stroke}-stroke: "
                          "mean current residual", "residual (baseline sd)")
    figure_legend(fig, axes, ncol=4)
    fig.savefig(path, dpi=72)
    return path


def _stroke_panel(ax: Any, title: str, ylabel: str, fontsize: float | None = None) -> None:
    """One stroke's panel of the residual and location figures: against measured
    position."""
    ax.set_title(title, **({} if fontsize is None else {"fontsize": fontsize}))
    ax.set_xlabel("measured position (mm)")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)


def figure_legend(fig: Any, axes: Any, ncol: int) -> None:
    """One legend for every panel (the same conditions in each), under the panels, in a
    size that reads at the page's scale: not one per row on top of the curves."""
    seen: dict[str, Any] = {}
    for ax in np.ravel(axes):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            seen.setdefault(lab, h)
    if seen:
        fig.legend(list(seen.values()), list(seen), loc="outside lower center", ncol=ncol,
                   fontsize=9, frameon=False)


def location_figure(study: Study, path: Path) -> Path:
    """Is there a place? Per load and stroke, every condition's mean current residual
    (baseline sd) against measured position, less its median over the stroke and
    averaged over one lead of travel (which removes a once-per-revolution line, the
    periodic feature's, and most of the sample noise): a defect at one spot of the screw
    stands out where the nut passes it in both strokes, at the same place in every stage.
    The held-out healthy runs (black) show how far two sets of healthy runs differ with
    no fault at all."""
    from matplotlib.figure import Figure
    loads = study.loads
    fig = Figure(figsize=(12, 3.2 * len(loads) + 0.9), layout="constrained")
    axes = fig.subplots(len(loads), 2, squeeze=False)
    conds = [study.healthy_condition] + study.fault_conditions
    cmap = __import__("matplotlib").colormaps["viridis"]
    lead = study.baseline.lead_mm
    for i, load in enumerate(loads):
        for j, stroke in enumerate(("out", "in")):
            ax = axes[i][j]
            for k, cond in enumerate(conds):
                z, pos = mean_profile(study.results.get(cond, {}).get(load, []), stroke)
                if len(z) < 3:
                    continue
                step = float(np.median(np.abs(np.diff(pos)))) or 1.0
                w = max(1, min(len(z), int(round((lead or 5 * step) / step))))
                zz = np.convolve(z - np.median(z), np.ones(w) / w, mode="same")
                healthy = cond == study.healthy_condition
                ax.plot(pos, zz, color="k" if healthy else cmap(k / max(1, len(conds) - 1)),
                        lw=1.6 if healthy else 0.9,
                        label=f"{cond} (held-out runs)" if healthy else
                        study.condition_label(cond))
            span = f"one lead ({lead:g} mm)" if lead else "5 samples"
            _stroke_panel(ax, f"load {study.baseline.load_text(load)}, {stroke}-stroke: "
                          f"mean residual over {span}",
                          "residual less its median (baseline sd)", fontsize=9)
    figure_legend(fig, axes, ncol=4)
    fig.savefig(path, dpi=72)
    return path


NO_FAULT = ("No fault table scored (none in the folder, or none at a load the calibration "
            "runs have: see Not scored): the study measured the held-out healthy false-alarm "
            "rate only, no detection rate.")


def detection_figure(study: Study, path: Path) -> Path:
    """Detection rate per stage and load, the bench's detector beside the z-score."""
    from matplotlib.figure import Figure
    conds = study.fault_conditions
    fig = Figure(figsize=(10, 4.6), layout="constrained")
    ax = fig.subplots()
    if not conds:                     # healthy runs only: a false-alarm check
        ax.text(0.5, 0.5, NO_FAULT, ha="center", va="center", wrap=True)
        ax.set_axis_off()
        fig.savefig(path, dpi=90)
        return path
    x = np.arange(len(conds))
    width = 0.8 / max(1, len(study.loads))
    for i, load in enumerate(study.loads):
        st = study.summary["loads"][f"{load:g}"]["stages"]
        ours = [st.get(c, {}).get("rate", np.nan) for c in conds]
        zs = [st.get(c, {}).get("zscore_rate", np.nan) for c in conds]
        xs = x + (i - (len(study.loads) - 1) / 2) * width
        bars = ax.bar(xs, ours, width,
                      label=f"baseline features, load {study.baseline.load_text(load)}")
        rng = [split_range(study, f"{load:g}", c) for c in conds]
        lo = [r["min"] if r else np.nan for r in rng]
        hi = [r["max"] if r else np.nan for r in rng]
        if np.isfinite(lo).any():
            mid = (np.asarray(lo) + np.asarray(hi)) / 2
            ax.errorbar(xs, mid, yerr=(np.asarray(hi) - np.asarray(lo)) / 2, fmt="none",
                        ecolor="0.5", elinewidth=1.2, capsize=2,
                        label="least to largest over the calibration splits" if i == 0
                        else None)
        ax.plot(xs, zs, "_", ms=14, mew=2,
                color=bars.patches[0].get_facecolor(), markeredgecolor="k")
    ax.axhline(0.9, color="r", ls="--", lw=0.8, label="goal 90 % (stages 6-8)")
    ax.set_xticks(x, [study.condition_label(c) for c in conds], rotation=0 if all(
        study.condition_label(c).isdigit() for c in conds) else 30, fontsize=8)
    ax.set_xlabel("stage (black ticks: plain z-score at the same false-alarm rate)")
    ax.set_ylabel("cycles flagged")
    ax.set_ylim(0, 1.05)
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=3,
               fontsize=8, frameon=False)
    ax.grid(alpha=0.3, axis="y")
    fig.savefig(path, dpi=90)
    return path


def _pct(x: float) -> str:
    """A rate in a per-stage cell, to the whole per cent (the tables' compact cells)."""
    return "-" if not math.isfinite(x) else f"{100 * x:.0f} %"


def _mm(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.1f}"


def _cv_blocks(sm: dict[str, Any]) -> list[Block]:
    """The healthy cross-validation's table (`population.cross_validate`)."""
    rows = [(load, row["cross_validation"]) for load, row in sm["loads"].items()
            if row.get("cross_validation")]
    if not rows:
        return []
    table = Table(["load", "healthy runs", "splits", "cycles flagged / judged",
                   "rate (95 % interval)", "effects named"], [],
                  numeric=[False, False, True, True, True, False])
    for load, cv in rows:
        eff = ", ".join(f"{e} {n}" for e, n in sorted(cv["effects"].items())) or "none"
        table.rows.append([load, ",".join(map(str, cv["runs"])), str(cv["splits"]),
                           f"{cv['flagged']} / {cv['judged']}",
                           f"{pct(cv['rate'])} ({ci(cv['rate_95'])})", eff])
    return [Paragraph(f"Healthy false alarms, cross-validated: {_choices(rows[0][1])} "
                      "calibrates (as above), the cycles of the other healthy runs are judged; "
                      "a measurement only, no threshold comes from it:"), table]


def _choices(cv: dict[str, Any]) -> str:
    """'every choice of k of the healthy runs', or, where `population.splits_of` drew a
    sample of them, how many of how many."""
    k, n = cv["k"], math.comb(len(cv["runs"]), cv["k"])
    if cv["splits"] < n:
        return (f"each of a fixed-seed sample of {cv['splits']} of the {n} choices of {k} "
                "of the healthy runs")
    return f"every choice of {k} of the healthy runs"


def split_range(study: Study, load: str, cond: str) -> dict[str, Any] | None:
    """A fault condition's detection rate over the cross-validation's calibration splits
    at one load (`population.split_rates`), None when the study has none."""
    cv = study.summary["loads"].get(load, {}).get("cross_validation") or {}
    r = cv.get("faults", {}).get(cond)
    return r if r and math.isfinite(r["min"]) else None


def _stage_table(study: Study) -> Table:
    """An empty table with a column per load, its rows to be one per fault condition."""
    return Table([study.stage_header] + [f"load {k}" for k in study.summary["loads"]], [],
                 numeric=[False] * (1 + len(study.summary["loads"])))


def _split_blocks(study: Study) -> list[Block]:
    """The detection rate of every stage under every choice of calibration runs."""
    sm = study.summary
    cvs = [row.get("cross_validation") or {} for row in sm["loads"].values()]
    if not any(cv.get("faults") for cv in cvs):
        return []
    cv0 = next(cv for cv in cvs if cv.get("faults"))
    table = _stage_table(study)
    for cond in study.fault_conditions:
        cells = []
        for load, row in sm["loads"].items():
            d, r = row["stages"].get(cond), split_range(study, load, cond)
            if d is None or r is None:
                cells.append("-")
                continue
            cells.append(f"{_pct(d['rate'])}; splits {_pct(r['min'])} / {_pct(r['median'])} "
                         f"/ {_pct(r['max'])}")
        table.rows.append([study.condition_label(cond)] + cells)
    return [Paragraph(
        f"Detection rate under every choice of calibration runs: each of the "
        f"{cv0['splits']} splits of the cross-validation ({_choices(cv0)}) calibrates a "
        "baseline and thresholds as above, and every fault cycle at that load is judged "
        "against them (a measurement only). Per stage and load: the rate of this study's "
        "calibration runs, then the least, median and largest over the splits. The spread "
        "is what the choice of healthy runs alone moves the rate by:"), table]


def _holdout_table(sm: dict[str, Any]) -> Table:
    table = Table(["load", "held-out healthy cycles flagged (95 % interval)",
                   "z-score threshold (matched)", "thresholds"], [],
                  numeric=[False, False, True, False])
    for load, row in sm["loads"].items():
        h = row["holdout"]
        thr = ", ".join(f"{k} {v:.3g}" for k, v in row["thresholds"].items())
        skip = f"; {h['not_judged']} incomplete not judged" if h.get("not_judged") else ""
        table.rows.append([load, f"{h['flagged']} / {h['cycles']} ({pct(h['rate'])}; "
                           f"{ci(h.get('rate_95'))}){skip}",
                           f"{row['zscore_threshold']:.3g}", thr])
    return table


def _detection_table(study: Study) -> Table:
    table = _stage_table(study)
    for cond in study.fault_conditions:
        cells = []
        for row in study.summary["loads"].values():
            d = row["stages"].get(cond)
            if d is None:
                cells.append("-")
                continue
            eff = ", ".join(f"{k} {v}" for k, v in sorted(d["effects"].items(),
                                                          key=lambda kv: -kv[1]))
            skip = f"; {d['not_judged']} incomplete not judged" if d.get("not_judged") else ""
            cells.append(f"{_pct(d['rate'])} ({_pct(d['zscore_rate'])}); {eff or 'none'}{skip}")
        table.rows.append([study.condition_label(cond)] + cells)
    return table


def _location_table(study: Study) -> Table:
    table = Table([study.stage_header, "load", "located / periodic or localised",
                   "position mm", "IQR mm", "out-stroke mm", "in-stroke mm"], [],
                  numeric=[False, False, False, True, True, True, True])
    for cond in study.fault_conditions:
        for load, row in study.summary["loads"].items():
            d = row["stages"].get(cond)
            if d is None:
                continue
            n = sum(v for k, v in d["effects"].items() if k in ("localised", "periodic"))
            table.rows.append([study.condition_label(cond), load, f"{d['located']} / {n}",
                               _mm(d["position_mm"]), _mm(d["position_iqr_mm"]),
                               _mm(d["out_mm"]), _mm(d["in_mm"])])
    return table


def document(study: Study, command: str) -> Document:
    """The report: thresholds, false alarms, detection per stage, location, cost, and the
    figures (files beside the page)."""
    sm = study.summary
    doc = Document().add(
        f"Command: `{command}`", Heading("Thresholds and false alarms"),
        f"Baseline: {sm['baseline']}. Thresholds from the calibration runs "
        f"{sm['calibrate_runs']} only (leave-one-run-out); held-out healthy runs "
        f"{sm['holdout_runs']}.", _holdout_table(sm), *_cv_blocks(sm),
        *goal_blocks(study), *[f"Not scored: {u}." for u in sm.get("unscored", [])])
    if not study.fault_conditions:
        return doc.add(NO_FAULT, *_cost_blocks(sm), *_figure_blocks(study))
    doc.add(Heading("Detection"), "Detection rate per stage (cycles flagged; in brackets the plain z-score at the "
            "same false-alarm rate) and the effect named:", _detection_table(study),
            *_split_blocks(study), Heading("Location"),
            "Where the named effect lies (flagged cycles named periodic or localised, and "
            "those of them located: the localised scan above its threshold; median position "
            "and interquartile range of the located ones, mm of measured travel; out- and "
            "in-stroke alone):", _location_table(study))
    return doc.add(*_cost_blocks(sm), *_figure_blocks(study))


def _figure_blocks(study: Study) -> list[Block]:
    return [Heading("Figures"),
            PageFigure("residual: the mean current residual along the stroke per condition",
                       src="residual.png"),
            PageFigure("detection: cycles flagged per stage and load, the plain z-score's as "
                       "black ticks", src="detection.png"),
            Paragraph("Is there a place? Each condition's mean residual averaged over one lead "
                      "of travel (the periodic line removed), less its median; the held-out "
                      "healthy runs in black:"),
            PageFigure("location: the mean residual over one lead of travel",
                       src="location.png")]


def markdown(study: Study, command: str) -> str:
    """The report as markdown (`document`)."""
    return document(study, command).markdown()


def _cost_blocks(sm: dict[str, Any]) -> list[Block]:
    """The cost table of the report."""
    c = sm["cost"]
    table = Table(["condition", "cycles", "wall s"], [])
    for k, v in c["wall_s"].items():
        table.rows.append([k, str(c["cycles_per_condition"][k]), f"{v:.2f}"])
    if c.get("cross_validation_s"):
        table.rows.append(["cross-validation over the calibration splits (healthy and fault "
                           "cycles)", "-", f"{c['cross_validation_s']:.2f}"])
    return [Heading("Cost"), Paragraph(
        f"Cost: one cycle's features and verdict {1e3 * c['cycle_s_median']:.2f} ms median, "
        f"{1e3 * c['cycle_s_max']:.0f} ms max (in a worker, {c['cycles']} cycles); wall time "
        "per condition over `bench.runtime.workers.run_all` (the start of the two Dask workers, once "
        "per study, is in the first condition's):"), table]


def write(study: Study, out: Path, command: str) -> dict[str, Path]:
    """baseline.json, study.json, residual.png, detection.png, location.png and
    report.md/.html."""
    from bench.reports import render_document
    out.mkdir(parents=True, exist_ok=True)
    paths = {"baseline": study.baseline.save(out / "baseline.json")}
    study.summary["baseline"] = study.baseline.describe()      # now with its file
    paths["json"] = out / "study.json"
    paths["json"].write_text(json.dumps(_jsonable(study.summary), indent=1))
    paths["residual"] = residual_figure(study, out / "residual.png")
    paths["detection"] = detection_figure(study, out / "detection.png")
    paths["location"] = location_figure(study, out / "location.png")
    doc = document(study, command)
    paths["md"] = out / "report.md"
    paths["md"].write_text("# Rig study\n\n" + doc.markdown())
    paths["html"] = out / "report.html"
    paths["html"].write_text(render_document(doc, title="Rig study",
                                             nav=[("#" + h.anchor, h.text) for h in doc.headings()]))
    return paths


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
