"""The `Profile` type: an ECU mode and set-points as functions of time.

Position set-points are nut positions (m); speed set-points are motor-shaft speeds
(rad/s), as in the thesis' open-loop tests (section 5.7.4). The profiles themselves are
in `bench.profiles.catalog` (the thesis' maneuvers) and `bench.profiles.maneuvers` (the diagnosis
maneuver); both build this type, so neither imports the other for it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Profile:
    name: str
    mode: int
    duration_s: float
    position: Callable[[np.ndarray], np.ndarray]
    speed: Callable[[np.ndarray], np.ndarray]
    kwargs: dict[str, Any] = field(default_factory=dict)
    params_overrides: dict[str, Any] = field(default_factory=dict)
    fundamental_hz: float = float("nan")   # command frequency (HUMS spectra, gap regimes)
    # named phases (name, start s, end s) of a composite profile (the flight's), else ()
    phases: tuple[tuple[str, float, float], ...] = ()

    def phase(self, name: str) -> tuple[float, float]:
        """(start s, end s) of the phase called `name` (KeyError if none)."""
        for n, t0, t1 in self.phases:
            if n == name:
                return t0, t1
        raise KeyError(name)

    def setpoint(self, t: float) -> tuple[float, float]:
        ta = np.array([t], dtype=float)
        return float(self.position(ta)[0]), float(self.speed(ta)[0])

    def setpoints(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(self.position(t), dtype=float),
                np.asarray(self.speed(t), dtype=float))

    def describe(self) -> str:
        args = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                         for k, v in self.kwargs.items())
        return f"{self.name}({args})"


FREQUENCY_KEYS = ("frequency_hz", "f0_hz", "f1_hz")
"""A profile's keywords that are frequencies of its set-point (sine, chirp, ...)."""


def check_sampled(kwargs: dict[str, Any], period_s: float, whose: str) -> None:
    """Refuse a set-point frequency in `kwargs` that a set-point sampled every SYNC period
    `period_s` cannot hold: above 0 and below half the SYNC rate (Nyquist); `whose` names
    the period in the message (e.g. "the node's"). A BenchError naming the flag."""
    from bench import BenchError
    top = 0.5 / period_s
    for key in FREQUENCY_KEYS:
        f = kwargs.get(key)
        if f is not None and not 0 < f < top:
            raise BenchError(f"--{key.replace('_', '-')} {f:g}: a set-point sampled every "
                             f"SYNC period ({period_s * 1e3:g} ms, {whose}) holds "
                             f"frequencies above 0 and below {top:g} Hz")
