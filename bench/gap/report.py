"""The `bench gap --report DIR` report: PNG figures and an index.html.

Figures: residual energy by regime and by frequency band (per signal and per path),
traces of the log against the nominal model and against the model with the chosen
effect(s) (before/after), and the path residuals over time with the regimes shaded.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from bench.gap import effects as E
from bench.gap import resim as R
from bench.gap.localise import BANDS, PATHS, REGIMES
from bench.gap.summary import f0_text, fmt_params, shrink_text, text

SIGNAL_UNITS = {"current_a": (1.0, "A"), "motor_speed_rad_s": (1.0, "rad/s"),
                "position_m": (1e3, "mm"), "encoder_position_m": (1e3, "mm")}
REGIME_COLOURS = {"reversal": "#d62728", "load_change": "#9467bd", "acceleration": "#ff7f0e",
                  "cruise": "#2ca02c", "dwell": "#c7c7c7"}


def _figure(width_in: float, height_in: float) -> Any:
    from matplotlib.figure import Figure  # matplotlib only when a report is asked for
    return Figure(figsize=(width_in, height_in))


def _bars(ax, table: dict[str, dict[str, float]], keys: list[str], title: str) -> None:
    rows = list(table)
    w = 0.8 / max(len(rows), 1)
    x = np.arange(len(keys))
    for i, r in enumerate(rows):
        ax.bar(x + i * w - 0.4 + w / 2, [100 * (table[r].get(k) or 0.0) for k in keys], w,
               label=r)
    ax.set_xticks(x, keys, rotation=20, fontsize=8)
    ax.set_ylabel("share of residual energy (%)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)


def write_report(res: Any, js: dict[str, Any], out: Path, doc: dict[str, Any]) -> Path:
    """Write the figures, index.html (from the diagnosis' `js`) and gap.json (`doc`, the
    one `bench gap --json` document) into `out`; returns the index path."""
    out.mkdir(parents=True, exist_ok=True)
    loc = res.localisation
    p = res.problem
    figs: list[tuple[str, str]] = []
    # -- regimes and bands ------------------------------------------------------------------
    fig = _figure(12, 7.5)
    axes = fig.subplots(2, 2)
    sig = loc["signals"]
    _bars(axes[0, 0], {s: {r: sig[s]["by_regime"][r]["energy_share"] for r in REGIMES}
                       for s in sig}, list(REGIMES), "signals: residual by regime")
    _bars(axes[0, 1], {s: sig[s]["by_band"] for s in sig}, [b[0] for b in BANDS],
          f"signals: residual by band ({f0_text(loc.get('fundamental_hz'))})")
    paths = {k: v for k, v in loc["paths"].items() if v.get("available")}
    if paths:
        _bars(axes[1, 0], {k: {r: v["by_regime"][r]["energy_share"] for r in REGIMES}
                           for k, v in paths.items()}, list(REGIMES), "paths: residual by regime")
        _bars(axes[1, 1], {k: v["by_band"] for k, v in paths.items()}, [b[0] for b in BANDS],
              "paths: residual by band")
    fig.tight_layout()
    fig.savefig(out / "residual_regime_band.png", dpi=110)
    figs.append(("residual_regime_band.png", "Residual energy by regime and frequency band"))
    # -- traces before / after -----------------------------------------------------------------
    nominal = p.info.get("nominal") or p.simulate()
    after = None
    if res.chosen is not None:
        after = p.simulate([E.get(n) for n in res.chosen.fit.effects], res.chosen.fit.theta)
    t = p.drive.t
    fig = _figure(13, 2.6 * len(R.SIGNALS))
    axes = fig.subplots(len(R.SIGNALS), 2, sharex=True)
    for i, s in enumerate(R.SIGNALS):
        k, u = SIGNAL_UNITS[s]
        ax = axes[i, 0]
        ax.plot(t, p.meas[s] * k, lw=0.7, color="k", label="log")
        ax.plot(t, nominal[s] * k, lw=0.8, color="tab:blue", label="nominal model")
        if after is not None:
            ax.plot(t, after[s] * k, lw=0.8, ls="--", color="tab:red",
                    label=f"model + {res.chosen.fit.name}")
        ax.set_ylabel(f"{s}\n({u})", fontsize=8)
        ax.axvline(t[p.n_fit - 1] if p.n_fit < p.n else t[-1], color="grey", lw=0.6, ls=":")
        ax = axes[i, 1]
        ax.plot(t, (p.meas[s] - nominal[s]) * k, lw=0.6, color="tab:blue", label="before")
        if after is not None:
            ax.plot(t, (p.meas[s] - after[s]) * k, lw=0.6, color="tab:red", label="after")
        ax.set_ylabel(f"residual ({u})", fontsize=8)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[0, 1].legend(fontsize=7, loc="upper right")
    axes[0, 0].set_title("log and models (dotted line: end of the fit part)", fontsize=10)
    axes[0, 1].set_title("residual before / after", fontsize=10)
    axes[-1, 0].set_xlabel("t (s)")
    axes[-1, 1].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(out / "traces_before_after.png", dpi=110)
    figs.append(("traces_before_after.png", "Traces and residuals before and after the "
                 "chosen effect"))
    if _fig_paths(loc, t, out):
        figs.append(("path_residuals.png", "Path residuals over time, regimes shaded"))
    (out / "gap.json").write_text(json.dumps(doc, indent=1))
    idx = out / "index.html"
    idx.write_text(_html(js, figs))
    return idx


def _fig_paths(loc: dict[str, Any], t: np.ndarray, out: Path) -> bool:
    """The path residuals over time with the regimes shaded (False: none to draw)."""
    pr = loc.get("_path_residuals", {})
    reg = loc.get("_regimes")
    if pr:
        fig = _figure(13, 2.2 * len(pr))
        axes = fig.subplots(len(pr), 1, sharex=True)
        axes = np.atleast_1d(axes)
        for ax, name in zip(axes, [q for q in PATHS if q in pr], strict=False):
            r = pr[name]
            scale = 1e6 if name == "screw" else 1.0
            unit = "um" if name == "screw" else loc["paths"][name]["unit"]
            if reg is not None:
                _shade(ax, t, reg)
            ax.plot(t, r * scale, lw=0.6, color="k")
            ax.set_ylabel(f"{name}\n({unit})", fontsize=8)
        axes[-1].set_xlabel("t (s)")
        axes[0].set_title("path residuals, the motion regimes shaded", fontsize=9)
        if reg is not None:
            axes[0].legend(handles=_regime_handles(reg), fontsize=7, ncol=5,
                           loc="lower left", bbox_to_anchor=(0.0, 1.12), frameon=False)
        fig.tight_layout()
        fig.savefig(out / "path_residuals.png", dpi=110)
        return True
    return False


def _regime_handles(reg: np.ndarray) -> list[Any]:
    """Legend entries of the shaded regimes the log has (dwell: unshaded)."""
    from matplotlib.patches import Patch
    present = {REGIMES[int(k)] for k in np.unique(reg)}
    return [Patch(facecolor=c, alpha=0.15 if r != "dwell" else 0.0, edgecolor="0.6",
                  label=r if r != "dwell" else "dwell (unshaded)")
            for r, c in REGIME_COLOURS.items() if r in present]


def _shade(ax, t: np.ndarray, reg: np.ndarray) -> None:
    edges = np.flatnonzero(np.diff(reg)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [len(reg)]])
    for a, b in zip(starts, ends, strict=True):
        name = REGIMES[int(reg[a])]
        if name == "dwell":
            continue
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color=REGIME_COLOURS[name], alpha=0.15, lw=0)


def _limit_cycle(js: dict[str, Any]) -> list[Any]:
    """The limit-cycle note (bench.gap.limitcycle) as a paragraph under the verdict."""
    from bench.reports import Paragraph, strong
    lc = js["localisation"].get("limit_cycle")
    return [Paragraph(strong("Limit cycle:") + " " + lc["note"])] if lc else []


def _size_notes(js: dict[str, Any]) -> list[Any]:
    """The verdict's size note (`bench.gap.summary.size_note`) as a paragraph under it."""
    from bench.gap.summary import size_note
    from bench.reports import Paragraph
    note = size_note(js)
    return [Paragraph(note, role="note")] if note else []


def ranking_table(js: dict[str, Any]) -> Any:
    """The candidates ranked by BIC (the page's summary table; the chosen row in bold)."""
    from bench.reports import Table, strong
    above = " above the healthy level" if js["localisation"].get("heldout_excess") else ""
    rows = []
    for i, c in enumerate(js["ranking"], 1):
        row = [str(c.get("rank", i)), c["effect"] + (" (chosen)" if c.get("chosen") else ""),
               fmt_params(c["params"]), shrink_text(c["heldout_shrink_pct"]),
               f"{c['gap_before']['normalised']:.3g} \u2192 {c['gap_after']['normalised']:.3g}",
               f"{c['score']['bic']:.1f}", "; ".join(c.get("suspect") or [])]
        rows.append([strong(x) for x in row] if c.get("chosen") else row)
    return Table(["#", "effect", "parameters (95 % CI)", f"held-out shrink{above} (%)",
                  "held-out gap (x floor, RMS)", "BIC", "suspect"], rows,
                 numeric=[True, False, False, True, True, True, False], role="summary")


def _html(js: dict[str, Any], figs: list[tuple[str, str]]) -> str:
    from bench.reports import (
        Document,
        Figure,
        Heading,
        Paragraph,
        Preformatted,
        link,
        render_document,
    )
    finding = (js.get("finding") or {}).get("line") or js["verdict"]
    doc = Document([Heading("Verdict: " + finding), *_size_notes(js), *_limit_cycle(js),
                    Preformatted(text(js)), Heading("Ranking by BIC, lower is better"),
                    ranking_table(js)])
    for f, cap in figs:
        doc.add(Heading(cap, 3), Figure("", src=f, alt=cap))
    doc.add(Paragraph(link("gap.json", "gap.json")))
    return render_document(doc, title="Sim-to-real gap diagnosis")
