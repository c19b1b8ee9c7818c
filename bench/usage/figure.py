"""The usage as a figure (matplotlib `Figure` API): load spectrum (revolutions per load
bin) and the rainflow matrices of position and load cycles."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.usage.settings import (
    LOAD_EDGES_N,
    LOAD_MEAN_EDGES_N,
    LOAD_RANGE_EDGES_N,
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
    shown = np.where(mat > 0, mat, np.nan)
    im = ax.imshow(shown, origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(mean_edges) - 1),
                  _labels(mean_edges, scale), rotation=60, fontsize=6)
    ax.set_yticks(range(len(range_edges) - 1), _labels(range_edges, scale), fontsize=6)
    ax.set_xlabel(f"cycle mean ({unit})")
    ax.set_ylabel(f"cycle range ({unit})")
    ax.set_title(title, fontsize=9)
    ax.figure.colorbar(im, ax=ax, label="cycles")


def usage_figure(s: UsageSummary, title: str):
    """A `Figure` with the load spectrum and the two rainflow matrices of `s`."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(12, 4), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(1, 3)
    inner = LOAD_EDGES_N[1:-1]
    centres = 0.5 * (inner[:-1] + inner[1:]) * 1e-3
    spec = s.load_spectrum_rev
    ax1.bar(centres, spec[1:-1], width=0.9 * np.diff(inner) * 1e-3)
    ax1.set_xlabel("axial load (kN), load cell")
    ax1.set_ylabel("screw revolutions")
    over = spec[0] + spec[-1]
    ax1.set_title(f"load spectrum; F_m {s.fm_n:.0f} N, life used {s.life_consumed:.2e}"
                  + (f"; {over:.3g} rev beyond +-20 kN" if over else ""), fontsize=9)
    _matrix(ax2, s.position_rainflow, POS_RANGE_EDGES_M, POS_MEAN_EDGES_M, 1e3, "mm",
            f"position cycles (rainflow): {s.position_cycles:g}")
    _matrix(ax3, s.load_rainflow, LOAD_RANGE_EDGES_N, LOAD_MEAN_EDGES_N, 1e-3, "kN",
            f"load cycles (rainflow): {s.load_cycles:g}")
    fig.suptitle(title, fontsize=10)
    return fig


def save_usage_figure(s: UsageSummary, title: str, path: Path) -> Path:
    usage_figure(s, title).savefig(path, dpi=110)
    return path
