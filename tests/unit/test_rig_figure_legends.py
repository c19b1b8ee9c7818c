"""The rig study's figures keep their legends clear of the data and the labels: the
detection figure's legend sat on its slanted condition names, the residual and
location figures had a 6-point legend inside a panel per row, over the curves."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench.rig.report import detection_figure, figure_legend

pytestmark = pytest.mark.unit

CONDS = ["backlash1_runs1-5", "lackLubrication1_runs1-5"] + [f"spalling{k}" for k in range(1, 9)]


def _study() -> SimpleNamespace:
    stages = {c: {"rate": 0.5 + 0.04 * k, "zscore_rate": 0.3} for k, c in enumerate(CONDS)}
    faults = {c: {"min": 0.2, "max": 0.9} for c in CONDS}
    loads = {f"{x:g}": {"stages": stages, "cross_validation": {"faults": faults}}
             for x in (-40.0, 20.0, 40.0)}
    return SimpleNamespace(fault_conditions=CONDS, loads=[-40.0, 20.0, 40.0],
                           summary={"loads": loads}, condition_label=lambda c: c,
                           baseline=SimpleNamespace(load_text=lambda x: f"{x:g} kgf"))


def test_detection_legend_clear_of_the_condition_names(tmp_path, monkeypatch):
    drawn: list[Figure] = []
    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig",
                        lambda self, *a, **k: (drawn.append(self), save(self, *a, **k)))
    detection_figure(_study(), tmp_path / "detection.png")
    (fig,) = drawn
    (ax,) = fig.axes
    assert ax.get_legend() is None and len(fig.legends) == 1
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    r = canvas.get_renderer()
    box = fig.legends[0].get_window_extent(r)
    ticks = [t.get_window_extent(r) for t in ax.get_xticklabels() if t.get_text()]
    assert len(ticks) == len(CONDS)
    assert not any(box.overlaps(t) for t in ticks)
    assert box.y1 <= ax.xaxis.label.get_window_extent(r).y0 + 1
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "baseline features, load -40 kgf" in labels


def test_one_readable_legend_under_the_panels():
    fig = Figure(figsize=(12, 6), layout="constrained")
    axes = fig.subplots(2, 2, squeeze=False)
    x = np.linspace(20, 140, 100)
    for ax in axes.ravel():
        for k, name in enumerate(("healthy (held-out runs)", "spalling1", "spalling8")):
            ax.plot(x, np.sin(x / 7 + k), label=name)
    figure_legend(fig, axes, ncol=4)
    assert not any(ax.get_legend() for ax in axes.ravel())
    (leg,) = fig.legends
    assert [t.get_text() for t in leg.get_texts()] == ["healthy (held-out runs)",
                                                       "spalling1", "spalling8"]
    assert leg.get_texts()[0].get_fontsize() >= 8
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    r = canvas.get_renderer()
    bottom = min(ax.get_tightbbox(r).y0 for ax in axes.ravel())
    assert leg.get_window_extent(r).y1 <= bottom + 1
