"""The gap report's path-residual figure names its shaded regimes in a legend (it listed
them as hex codes in the title), one entry per regime the log has."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from bench.gap import report as G


def test_path_residuals_have_a_regime_legend(tmp_path, monkeypatch):
    drawn: list = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: drawn.append(self))
    t = np.arange(400) * 1e-3
    reg = np.repeat([0, 2, 3, 2, 0, 4, 0, 3], 50)           # no load change
    loc = {"_path_residuals": {"drive": np.sin(t), "screw": 1e-6 * np.cos(t)},
           "_regimes": reg, "paths": {"drive": {"unit": "A"}, "screw": {"unit": "m"}}}
    assert G._fig_paths(loc, t, tmp_path)
    ax = drawn[0].axes[0]
    assert "#" not in ax.get_title()
    labels = [x.get_text() for x in ax.get_legend().get_texts()]
    assert labels == ["reversal", "acceleration", "cruise", "dwell (unshaded)"]
