"""The usage figure reads on a run of small loads: the load spectrum is drawn over the
bins the run used (in N when the span is small), not over +-20 kN, and a rainflow matrix
with no cycle says so instead of drawing an empty image with a -0.1..0.1 colour bar."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.signals.trace import Trace
from bench.usage import usage_of_trace
from bench.usage.figure import usage_figure
from plant_rt.params import PlantParams

RATIO = PlantParams().reducer.ratio
DT = 1e-3


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    from bench.usage.tracker import Tracker
    Tracker(1.0).push(np.zeros(2))


def _summary(load_n: np.ndarray):
    t = np.arange(len(load_n)) * DT
    rev = 2.0 * np.sin(2 * math.pi * 2.0 * t)        # +-2 screw revolutions at 2 Hz
    return usage_of_trace(Trace({"t_s": t, "motor_angle_rad": rev * 2 * math.pi / RATIO,
                                 "load_force_n": load_n}, {"period_s": DT}))


def test_small_loads_zoom_the_spectrum_and_say_no_load_cycles():
    n = 3000
    s = _summary(3.0 + 0.5 * np.sin(np.arange(n) * 0.01))         # a few N
    assert s.load_cycles == 0
    fig = usage_figure(s, "small loads")
    spec, _, loads = fig.axes[:3]
    lo, hi = spec.get_xlim()
    assert -1500 <= lo < 0 < hi <= 1500 and "(N)" in spec.get_xlabel()
    assert not loads.images                                        # no empty image ...
    assert len(fig.axes) == 3 + sum(bool(ax.images) for ax in fig.axes[1:3])  # nor its bar
    assert any("no cycles counted" in t.get_text() for t in loads.texts)


def test_large_loads_in_kn_with_their_matrix():
    n = 3000
    s = _summary(5000.0 * np.sin(2 * math.pi * 3.0 * np.arange(n) * DT))
    fig = usage_figure(s, "5 kN")
    spec, _, loads = fig.axes[:3]
    lo, hi = spec.get_xlim()
    assert "(kN)" in spec.get_xlabel() and -7 < lo < -5 and 5 < hi < 7
    assert loads.images and s.load_cycles > 0
