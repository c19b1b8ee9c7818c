"""Excitation maneuvers for gap diagnosis: position-loop set-points rich in regimes.

A log made for diagnosis should hold every regime the localisation splits on (dwell,
acceleration at the current limit, cruise, reversal) in both halves, so the second half
can serve as held-out data for the first. `excitation()` is such a maneuver, built from
segments; its two halves use different amplitudes and frequencies so the held-out half
is another maneuver, not a copy.

Position set-points are nut positions (m); the ECU is in position mode throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.profiles import Profile
from bench.trace import MODE_POSITION


@dataclass(frozen=True)
class Segment:
    """One piece of a set-point: kind 'hold', 'sine', 'step' or 'ramp' over duration_s."""
    kind: str
    duration_s: float
    amplitude_m: float = 0.0      # sine amplitude, or step/ramp target (absolute)
    frequency_hz: float = 0.0     # sine frequency


def _build(segments: list[Segment]):
    starts = np.cumsum([0.0] + [s.duration_s for s in segments])

    def pos(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.zeros_like(t)
        level = 0.0
        for seg, t0 in zip(segments, starts[:-1], strict=True):
            m = (t >= t0) & (t < t0 + seg.duration_s)
            tl = t[m] - t0
            if seg.kind == "hold":
                out[m] = level
            elif seg.kind == "sine":
                out[m] = level + seg.amplitude_m * np.sin(2 * math.pi * seg.frequency_hz * tl)
            elif seg.kind == "step":
                level = seg.amplitude_m
                out[m] = level
            elif seg.kind == "ramp":
                out[m] = level + (seg.amplitude_m - level) * tl / seg.duration_s
                level = seg.amplitude_m
            else:  # pragma: no cover - programming error
                raise ValueError(seg.kind)
        out[t >= starts[-1]] = level
        return out

    return pos, float(starts[-1])


HALF_A = [
    Segment("hold", 0.3),
    Segment("sine", 1.5, 0.5e-3, 2.0),           # thesis H4: +-0.5 mm at 2 Hz
    Segment("hold", 0.4),
    Segment("step", 0.6, 3.0e-3),                # current-limited acceleration, 251 rad/s
    Segment("ramp", 0.3, 0.0),                   # cruise at 10 mm/s back to 0
    Segment("hold", 0.3),
    Segment("sine", 1.5, 0.25e-3, 4.0),
    Segment("hold", 0.1),
]
HALF_B = [
    Segment("hold", 0.2),
    Segment("sine", 1.5, 0.8e-3, 3.0),
    Segment("hold", 0.3),
    Segment("step", 0.6, -2.5e-3),
    Segment("ramp", 0.5, 0.0),                   # cruise at 5 mm/s
    Segment("hold", 0.4),
    Segment("sine", 1.5, 1.0e-3, 1.0),
]


def excitation(duration_s: float = 10.0) -> Profile:
    """The diagnosis maneuver: half A then half B (each 5 s), truncated or repeated to
    `duration_s`. Fundamental for the frequency split: 2 Hz (half A's first sine)."""
    segs = HALF_A + HALF_B
    pos, length = _build(segs)

    def position(t: np.ndarray) -> np.ndarray:
        return pos(np.mod(np.asarray(t, dtype=float), length))

    def speed(t: np.ndarray) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    return Profile("gap-excitation", MODE_POSITION, float(duration_s), position, speed,
                   {"duration_s": float(duration_s)}, fundamental_hz=2.0)


COMPACT_A = [Segment("hold", 0.1), Segment("sine", 1.0, 0.5e-3, 2.0),
             Segment("step", 0.35, 2.0e-3), Segment("ramp", 0.3, 0.0), Segment("hold", 0.25)]
COMPACT_B = [Segment("hold", 0.1), Segment("sine", 1.0, 0.7e-3, 3.0),
             Segment("step", 0.35, -1.5e-3), Segment("ramp", 0.3, 0.0), Segment("hold", 0.25)]


def compact() -> Profile:
    """A 4 s version of `excitation` (two 2 s halves with every regime), for tests and
    quick checks."""
    pos, length = _build(COMPACT_A + COMPACT_B)
    return Profile("gap-compact", MODE_POSITION, length, pos,
                   lambda t: np.zeros_like(np.asarray(t, dtype=float)),
                   {"duration_s": length}, fundamental_hz=2.0)
