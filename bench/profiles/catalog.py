"""Set-point profiles: the thesis' test maneuvers plus a chirp, the RUL run and a seeded
flight (`bench.profiles.flight`), by name.

Each builds a `bench.profiles.setpoints.Profile` (ECU mode and set-points as functions of time);
the gap diagnosis maneuver comes from `bench.profiles.maneuvers`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from bench import BenchError
from bench.profiles.flight import flight
from bench.profiles.maneuvers import excitation
from bench.profiles.setpoints import Profile
from bench.signals.trace import MODE_POSITION, MODE_SPEED


def _zeros(t: np.ndarray) -> np.ndarray:
    return np.zeros_like(t, dtype=float)


def step(amplitude_m: float = 0.04, start_s: float = 0.01, duration_s: float = 1.2) -> Profile:
    """Position step (section 5.7.1: at 0.01 s; full stroke, taken here as 40 mm)."""
    return Profile("step", MODE_POSITION, duration_s,
                   lambda t: np.where(t >= start_s, amplitude_m, 0.0), _zeros,
                   dict(amplitude_m=amplitude_m, start_s=start_s, duration_s=duration_s))


def sine(amplitude_m: float = 0.5e-3, frequency_hz: float = 2.0, cycles: float = 4.0,
         duration_s: float | None = None) -> Profile:
    """Position sine A sin(2 pi f t) (sections 5.7.3-5.7.4, 6.4.2)."""
    dur = duration_s if duration_s is not None else cycles / frequency_hz
    w = 2 * math.pi * frequency_hz
    return Profile("sine", MODE_POSITION, dur, lambda t: amplitude_m * np.sin(w * t), _zeros,
                   dict(amplitude_m=amplitude_m, frequency_hz=frequency_hz, duration_s=dur),
                   fundamental_hz=frequency_hz)


def velocity_step(speed_rad_s: float = 30.0, start_s: float = 0.0, stop_s: float = 0.2,
                  duration_s: float = 0.3) -> Profile:
    """Open-loop motor speed step (section 6.4.1): 30 rad/s from 0 s to 0.2 s, 0.3 s run."""
    return Profile("velocity-step", MODE_SPEED, duration_s, _zeros,
                   lambda t: np.where((t >= start_s) & (t < stop_s), speed_rad_s, 0.0),
                   dict(speed_rad_s=speed_rad_s, start_s=start_s, stop_s=stop_s,
                        duration_s=duration_s))


def velocity_cosine(amplitude_rad_s: float = 30.0, frequency_hz: float = 2.0,
                    cycles: float = 4.0) -> Profile:
    """Open-loop motor speed cosine (section 6.4.1): +-30 rad/s, 2 Hz, four periods."""
    w = 2 * math.pi * frequency_hz
    return Profile("velocity-cosine", MODE_SPEED, cycles / frequency_hz, _zeros,
                   lambda t: amplitude_rad_s * np.cos(w * t),
                   dict(amplitude_rad_s=amplitude_rad_s, frequency_hz=frequency_hz,
                        cycles=cycles), fundamental_hz=frequency_hz)


def chirp(amplitude_m: float = 0.5e-3, f0_hz: float = 0.5, f1_hz: float = 10.0,
          duration_s: float = 10.0) -> Profile:
    """Position chirp, frequency rising exponentially from f0 to f1 over the run."""
    if f0_hz <= 0 or f1_hz <= 0:
        raise BenchError("chirp frequencies must be > 0")
    k = math.log(f1_hz / f0_hz) / duration_s if f1_hz != f0_hz else 0.0

    def pos(t: np.ndarray) -> np.ndarray:
        if k == 0.0:
            phase = 2 * math.pi * f0_hz * t
        else:
            phase = 2 * math.pi * f0_hz * (np.exp(k * t) - 1.0) / k
        return amplitude_m * np.sin(phase)

    return Profile("chirp", MODE_POSITION, duration_s, pos, _zeros,
                   dict(amplitude_m=amplitude_m, f0_hz=f0_hz, f1_hz=f1_hz,
                        duration_s=duration_s))


def rul(duration_s: float = 120.0, amplitude_m: float = 0.5e-3,
        frequency_hz: float = 2.0) -> Profile:
    """The run-to-failure run of section 6.5: the H4 sine for 120 s with the degradation
    schedule (preload falling linearly, backlash and friction growing exponentially)."""
    base = sine(amplitude_m, frequency_hz, duration_s=duration_s)
    return Profile("rul", MODE_POSITION, duration_s, base.position, base.speed,
                   dict(duration_s=duration_s, amplitude_m=amplitude_m,
                        frequency_hz=frequency_hz),
                   {"schedule.kind": "rul", "schedule.duration_s": duration_s},
                   fundamental_hz=frequency_hz)


def gap_excitation(duration_s: float = 10.0, load_n: float = 2000.0) -> Profile:
    """The gap diagnosis maneuver (`bench.profiles.maneuvers.excitation`): 1-4 Hz sines,
    current-limited steps, cruise ramps and dwells under a `load_n` N sine load."""
    return excitation(duration_s, load_n)


PROFILES: dict[str, Callable[..., Profile]] = {
    "step": step, "sine": sine, "velocity-step": velocity_step,
    "velocity-cosine": velocity_cosine, "chirp": chirp, "rul": rul,
    "gap-excitation": gap_excitation, "flight": flight,
}


def make_profile(name: str, **kwargs: Any) -> Profile:
    """The profile `name` with keyword parameters; BenchError on unknown name/keyword."""
    try:
        factory = PROFILES[name]
    except KeyError:
        raise BenchError(f"unknown profile {name!r} (choose from "
                         f"{', '.join(PROFILES)})") from None
    import inspect
    sig = inspect.signature(factory)
    for k, v in kwargs.items():
        if k not in sig.parameters:
            raise BenchError(f"profile {name!r} has no parameter {k!r} (it has "
                             f"{', '.join(sig.parameters)})")
        if v is not None:
            check_parameter(name, k, v)
    prof = factory(**{k: v for k, v in kwargs.items() if v is not None})
    if not (math.isfinite(prof.duration_s) and prof.duration_s > 0):
        raise BenchError(f"profile {name!r}: duration_s must be > 0 s, got {prof.duration_s}")
    return prof


# keyword -> (lowest value, whether the lowest value itself is allowed, unit); every
# other numeric keyword (amplitudes, speeds, loads: a sign is a direction) only has to
# be finite
DOMAINS: dict[str, tuple[float, bool, str]] = {
    "frequency_hz": (0.0, False, "Hz"), "f0_hz": (0.0, False, "Hz"),
    "f1_hz": (0.0, False, "Hz"), "cycles": (0.0, False, ""),
    "duration_s": (0.0, False, "s"), "start_s": (0.0, True, "s"), "stop_s": (0.0, True, "s"),
    "severity": (0.0, False, ""), "turbulence_m": (0.0, True, "m"), "seed": (0.0, True, ""),
}


def check_parameter(profile: str, name: str, value: Any) -> None:
    """BenchError unless `value` is a finite number within the domain of keyword `name`
    (DOMAINS): the one check of every profile parameter, whichever the profile."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise BenchError(f"profile {profile!r}: {name} must be a finite number, got {value!r}")
    if name in DOMAINS:
        low, closed, unit = DOMAINS[name]
        if value < low or (value == low and not closed):
            op = ">=" if closed else ">"
            raise BenchError(f"profile {profile!r}: {name} must be {op} {low:g}"
                             f"{' ' + unit if unit else ''}, got {value:g}")


def profile_args(name: str) -> dict[str, float]:
    """Keyword parameters of a profile with their defaults (for CLI flags)."""
    import inspect
    sig = inspect.signature(PROFILES[name])
    return {k: p.default for k, p in sig.parameters.items()}
