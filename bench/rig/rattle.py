"""A play's rattle: the current rough along the whole travel (the `rattle` feature of
`features.cycle_features`, naming-only).

A nut no longer held on both flanks by its preload moves within its play as the drive's
force ripples, so the current's sample-to-sample changes grow along the whole travel.
Each stroke's travel residual in amperes, less its constant, its slope and (with the
screw's lead) its once-per-revolution line, is differenced, and the median square of the
differences is taken over what the baseline's per-sample spread gives (about 1 for white
noise of that spread). The median, not the mean: a rattle is along the whole travel,
while a spot's transient makes a few large differences only. The feature is the rougher stroke's: a one-sided load holds
the nut on one flank in one direction more than in the other (as for the take-up). A
spot on the raceway moves the current where the nut passes it, and the lead's line is
left out: neither makes the whole stroke rough.
"""

from __future__ import annotations

import numpy as np

CHI2_1_MEDIAN = 0.45493642311957283
"""The median of a chi-square with 1 degree of freedom: the median square of a normal
difference over its variance."""


def roughness(r: np.ndarray, std: np.ndarray, pos: np.ndarray, lead_mm: float | None
              ) -> float:
    """One stroke's roughness on its travel (module doc): the median square of the
    sample-to-sample differences of the current residual `r` (A), less its constant, its
    slope and, with the screw's lead, its line at the lead at the measured positions
    `pos` (least squares), over what white noise of the baseline's per-sample spread `std`
    gives (the median of a chi-square with 1 degree of freedom times 2 std^2 a
    difference); NaN on fewer than 8 samples."""
    n = len(r)
    if n < 8:
        return float("nan")
    a = np.empty((4 if lead_mm else 2, n))   # the constant, the slope, the lead's line
    a[0] = 1.0
    a[1] = np.arange(n) - (n - 1) / 2.0
    if lead_mm:
        ph = (2.0 * np.pi / lead_mm) * pos
        a[2] = np.cos(ph)
        a[3] = np.sin(ph)
    try:                                        # least squares (the normal equations)
        coef = np.linalg.solve(a @ a.T, a @ r)
    except np.linalg.LinAlgError:               # a nut that did not move: columns alike
        coef = np.linalg.lstsq(a.T, r, rcond=None)[0]
    d = np.diff(r - coef @ a)
    s2 = std * std
    den = float(np.mean(s2[1:] + s2[:-1])) * CHI2_1_MEDIAN
    return float(np.median(d * d)) / den if den > 0 else float("nan")
