"""The usage as a figure (matplotlib `Figure` API): load spectrum (revolutions per load
bin) and the rainflow matrices of position and load cycles."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.usage.settings import (
    LOAD_EDGES_N,
    LOAD_MAX_N,
    LOAD_MEAN_EDGES_N,
    LOAD_RANGE_EDGES_N,
    LOAD_STEP_N,
    POS_MEAN_EDGES_M,
    POS_RANGE_EDGES_M,
)
from bench.usage.summary import UsageSummary


def _labels(edges: np.ndarray, scale: float) -> list[str]:
    out = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        if np.isinf(lo):
            out.append(f"<{hi * scale:g}")
        elif np.isinf(hi):
            out.append(f">={lo * scale:g}")
        else:
            out.append(f"{lo * scale:g}-{hi * scale:g}")
    return out


def _matrix(ax, mat: np.ndarray, range_edges: np.ndarray, mean_edges: np.ndarray,
            scale: float, unit: str, title: str) -> None:
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(f"cycle mean ({unit})")
    ax.set_ylabel(f"cycle range ({unit})")
    ax.set_xticks(range(len(mean_edges) - 1),
                  _labels(mean_edges, scale), rotation=60, fontsize=6)
    ax.set_yticks(range(len(range_edges) - 1), _labels(range_edges, scale), fontsize=6)
    if not np.any(mat > 0):            # no cycle counted: no colour scale to read
        ax.set_xlim(-0.5, len(mean_edges) - 1.5)
        ax.set_ylim(-0.5, len(range_edges) - 1.5)
        ax.text(0.5, 0.5, "no cycles counted:\nevery swing stayed within\nthe counter's "
                "hysteresis", ha="center", va="center", transform=ax.transAxes, fontsize=9,
                color="0.3")
        return
    shown = np.where(mat > 0, mat, np.nan)
    im = ax.imshow(shown, origin="lower", aspect="auto", cmap="viridis")
    ax.figure.colorbar(im, ax=ax, label="cycles")


def _spectrum(ax, s: UsageSummary) -> None:
    """Revolutions per 500 N load bin, zoomed to the bins the run used (one empty bin
    either side, at least +-1 kN), in N below 5 kN of span, else kN."""
    inner = LOAD_EDGES_N[1:-1]
    spec = s.load_spectrum_rev[1:-1]
    used = np.flatnonzero(spec > 0)
    lo, hi = (inner[0], inner[-1]) if not len(used) else (inner[max(used[0] - 1, 0)],
                                                          inner[min(used[-1] + 2, len(inner) - 1)])
    lo, hi = min(lo, -1e3), max(hi, 1e3)
    scale, unit = (1.0, "N") if hi - lo < 5e3 else (1e-3, "kN")
    centres = 0.5 * (inner[:-1] + inner[1:])
    ax.bar(centres * scale, spec, width=0.9 * np.diff(inner) * scale)
    ax.set_xlim(lo * scale, hi * scale)
    ax.set_xlabel(f"axial load ({unit}), load cell; bins of {LOAD_STEP_N:g} N")
    ax.set_ylabel("screw revolutions")
    over = s.load_spectrum_rev[0] + s.load_spectrum_rev[-1]
    fm = f"{s.fm_n:.0f}" if abs(s.fm_n) >= 10 else f"{s.fm_n:.2g}"
    ax.set_title(f"load spectrum; F_m {fm} N, L10 life used {s.life_consumed:.2e}"
                 + (f"; {over:.3g} rev beyond +-{LOAD_MAX_N * 1e-3:g} kN" if over else ""),
                 fontsize=9)


def usage_figure(s: UsageSummary, title: str):
    """A `Figure` with the load spectrum and the two rainflow matrices of `s`."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(12, 4), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(1, 3)
    _spectrum(ax1, s)
    _matrix(ax2, s.position_rainflow, POS_RANGE_EDGES_M, POS_MEAN_EDGES_M, 1e3, "mm",
            f"position cycles (rainflow): {s.position_cycles:g}")
    _matrix(ax3, s.load_rainflow, LOAD_RANGE_EDGES_N, LOAD_MEAN_EDGES_N, 1e-3, "kN",
            f"load cycles (rainflow): {s.load_cycles:g}")
    fig.suptitle(title, fontsize=10)
    return fig


def save_usage_figure(s: UsageSummary, title: str, path: Path) -> Path:
    usage_figure(s, title).savefig(path, dpi=110)
    return path
