"""Estimates of a measured signal's properties from its own samples.

`noise_floor` is the white-noise sigma the rig calibration's floor (`bench.gap.rigcal`),
the gap fits' weights (`bench.gap.problem.noise_std`) and the usage counters' hysteresis
rule (`bench.usage.hysteresis`) all use; it sits at the top of `bench` so that the
packages below the gap diagnosis (usage) reach it without importing the gap.
"""

from __future__ import annotations

import math

import numpy as np


def noise_floor(y: np.ndarray) -> float:
    """White-noise sigma of a measured signal from its own samples: the robust spread
    (1.4826 MAD) of its second differences / sqrt(6) (a smooth signal's second difference
    is ~0; white noise's has variance 6 sigma^2). NaN samples are skipped."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    if len(y) < 5:
        return float("nan")
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))
