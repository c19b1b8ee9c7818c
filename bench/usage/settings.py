"""The usage monitoring's own settings (a parameter set with units, ranges and sources)
and the fixed bins its spectra use, so that spectra of different runs add bin by bin.

The hystereses keep sensor noise and the closed loop's dither at standstill from
counting as motion, reversals or cycles (docs/usage.md, "Hysteresis"):

- reversals and revolutions: 2 um of nut travel (4e-4 screw revolutions, 26 counts of
  the 16384-count motor encoder through the 1:4 reducer): about 13 encoder counts of
  dither each way are ignored, while a gust oscillation of 0.1 mm still counts;
- position cycles: 20 um on the LVDT, ten times its noise (2 um std per SYNC sample),
  so that a noise peak of 5 sigma on each side does not close a cycle;
- load cycles: 100 N on the load cell, 50 times its 2 N noise and 50 of its 2 N steps;
  below the resolution of a spectrum of 500 N bins.

These are floors: on a noisier log (another rig's sensors) the position counter takes
`position_noise_factor` (10) x the log's own position noise when that is larger, the load
counter `load_noise_factor` (0, off) x its load noise (`bench.usage.hysteresis`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from bench.core.paramset import ParamSet
from plant_rt.params import P

PRELOAD_MODES = ("none", "double-nut")


@dataclass(frozen=True)
class UsageSettings(ParamSet):
    """How a trace is turned into usage (docs/usage.md)."""
    _group: ClassVar[str] = "usage"
    reversal_hysteresis_m: float = P(
        2e-6, "m", 0.0, 1e-3, "nut travel (from the encoder) the motion must retreat from "
        "its last extreme to count a reversal; also the play of the revolution counter",
        "chosen: above encoder dither, below gust oscillations (module docstring)")
    position_hysteresis_m: float = P(
        20e-6, "m", 0.0, 0.01, "LVDT position range below which a position cycle is "
        "filtered out before rainflow counting (a floor: position_noise_factor)",
        "chosen: 10 x LVDT noise std")
    load_hysteresis_n: float = P(
        100.0, "N", 0.0, 1e5, "load range below which a load cycle is filtered out before "
        "rainflow counting (a floor: load_noise_factor)", "chosen: 50 x load cell noise std")
    position_noise_factor: float = P(
        10.0, "-", 0.0, 100.0, "the position hysteresis is at least this many times the "
        "log's own position noise (white-noise sigma from the second differences); 0: the "
        "setting alone", "chosen: as the default, a 5-sigma noise peak each way does not "
        "close a cycle (bench.usage.hysteresis)")
    load_noise_factor: float = P(
        0.0, "-", 0.0, 100.0, "the load hysteresis is at least this many times the log's "
        "own load noise; 0 (default): the setting alone", "chosen: off, the second "
        "differences read a gust load's roughness as noise (bench.usage.hysteresis)")
    dwell_speed_m_s: float = P(
        0.5e-3, "m/s", 0.0, 1.0, "nut speed (encoder) below which the actuator dwells",
        "chosen: 12 x the encoder speed noise (0.2 rad/s on the motor = 0.04 mm/s)")
    fast_speed_m_s: float = P(
        10e-3, "m/s", 0.0, 10.0, "nut speed from which a motion is fast (between dwell and "
        "fast: slow)", "chosen: 1/6 of the 60 mm/s the motor reaches at 300 rad/s")
    preload_mode: str = P(
        "none", "-", None, None, "none: the measured axial load is the nut load (ISO "
        "3408-5 single nut); double-nut: the preload shares the load between the two nuts "
        "(F_j = F_pr (1 +- F/(2.83 F_pr))^1.5, nut lives combined with exponent 10/9)",
        "ISO 3408-5; manufacturer practice (Steinmeyer, 'Equivalent load: considering the "
        "preload with double nuts')", choices=PRELOAD_MODES)
    preload_n: float = P(
        -1.0, "N", -1.0, 1e5, "double-nut preload F_pr; -1: the trace's plant parameter "
        "effects.preload_n (0 when the trace does not carry it)", "chosen")


# fixed bins (edges), so that runs and actuators merge bin by bin
LOAD_STEP_N, LOAD_MAX_N = 500.0, 20000.0
LOAD_EDGES_N = np.concatenate([[-math.inf], np.arange(-40, 41) * LOAD_STEP_N, [math.inf]])
"""Load spectrum: signed axial load, 500 N bins over +-20 kN, and the two overflow bins."""
TEMP_EDGES_K = np.concatenate([[-math.inf], np.arange(230, 431, 10) * 1.0, [math.inf]])
"""Time at winding temperature: 10 K bins from 230 K to 430 K, and the overflow bins."""
POS_RANGE_EDGES_M = np.array([0.0, 50e-6, 100e-6, 200e-6, 500e-6, 1e-3, 2e-3, 5e-3, 10e-3,
                              20e-3, 50e-3, math.inf])
POS_MEAN_EDGES_M = np.concatenate([[-math.inf], np.arange(-50, 51, 10) * 1e-3, [math.inf]])
LOAD_RANGE_EDGES_N = np.array([0.0, 200.0, 500.0, 1e3, 2e3, 5e3, 1e4, 2e4, 5e4, math.inf])
LOAD_MEAN_EDGES_N = np.concatenate([[-math.inf], np.arange(-20, 21, 5) * 1e3, [math.inf]])
"""Rainflow matrices: cycle range (rows) by cycle mean (columns)."""
REGIMES = ("dwell", "slow", "fast")


def edge_label(lo: float, hi: float, scale: float = 1.0) -> str:
    """``a_b`` of a bin (``lo`` / ``hi`` for an open end), for flat keys."""
    def f(v: float) -> str:
        return f"{v * scale:g}".replace("-", "m")
    if math.isinf(lo):
        return f"lt_{f(hi)}"
    if math.isinf(hi):
        return f"ge_{f(lo)}"
    return f"{f(lo)}_{f(hi)}"
