"""Excitation maneuvers for gap diagnosis: position-loop set-points rich in regimes.

A log made for diagnosis should hold every regime the localisation splits on (dwell,
acceleration at the current limit, cruise, reversal) in both halves, so the second half
can serve as held-out data for the first. `excitation()` is such a maneuver, built from
segments; its two halves use different amplitudes and frequencies so the held-out half
is another maneuver, not a copy.

Position set-points are nut positions (m); the ECU is in position mode throughout.

The rig also applies an axial load, measured by the load cell (`load_force_n`): a slow
sine (`LOAD_HZ`, not a harmonic of the set-point lines) of `load_n`, 2 kN by default
(between the 1 and 3.5 kN of the thesis' disturbance test, section 5.7.3). Without it the contact force is mostly the
nut's Coulomb friction, of nearly constant magnitude, so a soft screw (deflection F/k)
looks like backlash, a torque-constant error like an inertia error (kt/J sets the
acceleration) and a lead error like an LVDT gain error. Under a load that crosses zero
these separate: backlash is a jump of the nut when the load changes sign, compliance a
deflection proportional to it; the current that holds the load is F p / (2 pi eta kt tau)
(kt, lead), the current that accelerates the rotor is J a / kt. `load_n=0` gives the
unloaded maneuver (a rig without a load actuator).

The module sits next to `bench.profiles.catalog` (which offers `excitation` as `gap-excitation`),
below the gap diagnosis that uses it, so the profiles do not import the gap package.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.profiles.setpoints import Profile
from bench.signals.trace import MODE_POSITION


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


LOAD_HZ = 0.37
"""Frequency of the maneuver's axial load (Hz): about two cycles per 5 s half."""


def load_overrides(load_n: float) -> dict[str, float | str]:
    """Plant load settings of the maneuver's rig: a sine of `load_n` N at LOAD_HZ."""
    if not math.isfinite(load_n):
        raise ValueError("load_n must be finite")
    if load_n == 0.0:
        return {}
    return {"load.kind": "sine", "load.amplitude_n": float(load_n),
            "load.frequency_hz": LOAD_HZ, "load.start_s": 0.0}


def excitation(duration_s: float = 10.0, load_n: float = 2000.0) -> Profile:
    """The diagnosis maneuver: half A then half B (each 5 s), truncated or repeated to
    `duration_s`, under a `load_n` N axial sine load (0: unloaded). Fundamental for the
    frequency split: 2 Hz (half A's first sine)."""
    segs = HALF_A + HALF_B
    pos, length = _build(segs)

    def position(t: np.ndarray) -> np.ndarray:
        return pos(np.mod(np.asarray(t, dtype=float), length))

    def speed(t: np.ndarray) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    return Profile("gap-excitation", MODE_POSITION, float(duration_s), position, speed,
                   {"duration_s": float(duration_s), "load_n": float(load_n)},
                   fundamental_hz=2.0, params_overrides=load_overrides(load_n))


COMPACT_A = [Segment("hold", 0.1), Segment("sine", 1.0, 0.5e-3, 2.0),
             Segment("step", 0.35, 2.0e-3), Segment("ramp", 0.3, 0.0), Segment("hold", 0.25)]
COMPACT_B = [Segment("hold", 0.1), Segment("sine", 1.0, 0.7e-3, 3.0),
             Segment("step", 0.35, -1.5e-3), Segment("ramp", 0.3, 0.0), Segment("hold", 0.25)]


def compact(load_n: float = 2000.0) -> Profile:
    """A 4 s version of `excitation` (two 2 s halves with every regime, the same load),
    for tests and quick checks."""
    pos, length = _build(COMPACT_A + COMPACT_B)
    return Profile("gap-compact", MODE_POSITION, length, pos,
                   lambda t: np.zeros_like(np.asarray(t, dtype=float)),
                   {"duration_s": length, "load_n": float(load_n)}, fundamental_hz=2.0,
                   params_overrides=load_overrides(load_n))
