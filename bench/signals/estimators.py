"""Estimates of a signal's properties from its own samples: one function each.

- `noise_floor`: the white-noise sigma the rig calibration's floor (`bench.rig.rigcal`),
  the gap fits' weights (`bench.gap.problem.noise_std`) and the usage counters'
  hysteresis rule (`bench.usage.hysteresis`) all use.
- `fundamental_hz`: the command's fundamental, stated or the strongest line of the
  set-point spectrum (eq. 6.3); the HUMS report and indexes (`bench.hums.report`,
  `bench.hums.comparison`, `bench.hums.periods`) and the gap's frequency bands
  (`bench.gap.localise`).
- `motion_regimes` (and `motion_direction`, `moving_threshold`): samples split by speed
  into rest and motion (and the bands above), with the direction; the gap's regimes
  (`bench.gap.localise`, `bench.rig.riggap`), a rig cycle's set-point phases
  (`bench.rig.cycles`) and the usage counters' dwell / slow / fast time
  (`bench.usage.accumulator`).

The module sits at the top of `bench` so that the packages below the gap diagnosis
(usage, hums) reach it without importing the gap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from scipy.signal import get_window

MOVING_FRACTION = 0.02
"""A set-point moves where its speed (or step) is above this share of its largest."""
MOVING_FLOOR = 1e-12
"""The least moving threshold (a set-point that never moves has no sample above it)."""


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


def _stated(value: Any) -> float:
    try:
        f = float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan
    return f if math.isfinite(f) and f > 0 else math.nan


def fundamental_hz(stated: Any = (), y: np.ndarray | None = None, dt: float = math.nan, *,
                   periodic: bool = False, clip_percentile: float | None = None) -> float:
    """The command's fundamental (Hz): the first of `stated` (one value or a sequence:
    the caller's, the trace's ``fundamental_hz`` metadata) that reads as a positive
    finite frequency, else the strongest line of the spectrum of the set-point `y`
    sampled every `dt` s (eq. 6.3, the mean removed, a Hann window), else NaN.

    `periodic` (the command's period, for per-period indexes and a trend): the line must
    hold at least half the set-point's variance and lie at two cycles of the record or
    more (else NaN: a step is not periodic), and is refined to a whole number of samples
    per period; the window is DFT-even, the amplitude calibrated by its coherent gain.
    Otherwise (a reference for frequency bands, found for any command): the strongest
    line above two cycles of the record, through a symmetric Hann window, `y` clipped
    first to +-its `clip_percentile` percentile of |y| (a set-point velocity, whose
    steps are spikes)."""
    for v in (stated if isinstance(stated, (list, tuple)) else (stated,)):
        given = _stated(v)
        if math.isfinite(given):
            return given
    if y is None:
        return math.nan
    y = np.asarray(y, float)
    if periodic:
        return _period_line(y, dt)
    if clip_percentile is not None:
        lim = np.percentile(np.abs(y), clip_percentile)
        y = np.clip(y, -lim, lim)
    y = y - y.mean()
    if not np.any(y):
        return math.nan
    f = np.fft.rfftfreq(len(y), dt)
    a = np.abs(np.fft.rfft(y * get_window("hann", len(y), fftbins=False)))
    keep = f > 2.0 / (len(y) * dt)
    if not keep.any():
        return math.nan
    return float(f[keep][np.argmax(a[keep])])


def _period_line(y: np.ndarray, dt: float) -> float:
    """`fundamental_hz` with `periodic`: the line, its share, its whole-sample period."""
    if np.ptp(y) == 0:
        return math.nan
    w = get_window("hann", len(y), fftbins=True)
    a = np.abs(np.fft.rfft((y - y.mean()) * w)) / w.sum()   # eq. 6.3, amplitude
    a[1:] *= 2.0
    if len(y) % 2 == 0:
        a[-1] /= 2.0                                          # Nyquist has no mirror
    f = np.fft.rfftfreq(len(y), dt)
    k = int(np.argmax(a[1:]) + 1)
    # a periodic command puts most of its variance in that line
    if a[k] ** 2 / 2 < 0.5 * np.var(y) or f[k] * len(y) * dt < 2:
        return math.nan
    per = round(1.0 / (f[k] * dt))
    return 1.0 / (per * dt)


def moving_threshold(v: np.ndarray, fraction: float = MOVING_FRACTION,
                     floor: float = MOVING_FLOOR) -> float:
    """The speed above which a set-point moves: `fraction` of its largest |v|, at least
    `floor`."""
    v = np.asarray(v, float)
    return max(fraction * float(np.max(np.abs(v))), floor) if len(v) else floor


def motion_regimes(v: np.ndarray, edges: Sequence[float],
                   at_edge: Literal["lower", "upper"] = "lower") -> np.ndarray:
    """The motion regime of each sample by its speed |v| against ascending `edges`: 0 at
    rest (below the first edge), k above the k-th edge (e.g. rest / slow / fast with
    two), -1 where v is not finite. A speed equal to an edge goes to the regime below
    it (`at_edge` "lower": moving means above the threshold) or above it ("upper")."""
    speed = np.abs(np.asarray(v, float))
    reg = np.searchsorted(np.asarray(edges, float), speed,
                          side="left" if at_edge == "lower" else "right")
    return np.where(np.isfinite(speed), reg, -1)


def motion_direction(v: np.ndarray, threshold: float) -> np.ndarray:
    """+1 where `v` moves out (above `threshold`), -1 in (below -`threshold`), 0 at rest
    or not finite (`motion_regimes` with one edge, signed)."""
    v = np.asarray(v, float)
    return np.where(motion_regimes(v, (threshold,)) > 0, np.sign(v), 0.0).astype(int)
