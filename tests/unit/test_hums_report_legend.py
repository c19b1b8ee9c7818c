"""The HUMS report's legends sit in a band above the data: no entry covers a trace
(the nut-position sine filled the whole frame, its legend sat on it)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from bench.hums.report import legend_above_data

pytestmark = pytest.mark.unit


@pytest.mark.parametrize("entries", [2, 5])
def test_legend_is_above_every_sample(entries):
    from matplotlib.figure import Figure
    fig = Figure(figsize=(5.5, 3.4))
    ax = fig.subplots()
    t = np.linspace(0, 5, 2000)
    for k in range(entries):
        ax.plot(t, 0.5 * np.sin(2 * np.pi * 2 * t + k), label=f"trace {k}")
    legend_above_data(ax, ncol=3 if entries > 2 else 2)
    fig.tight_layout()
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    box = ax.get_legend().get_window_extent(canvas.get_renderer())
    top_of_data = ax.transData.transform((0.0, 0.5))[1]
    assert box.y0 > top_of_data
    assert ax.get_ylim()[0] <= -0.5


def test_no_legend_without_labels():
    from matplotlib.figure import Figure
    ax = Figure().subplots()
    ax.plot([0, 1], [0, 1])
    legend_above_data(ax, ncol=2)
    assert ax.get_legend() is None
