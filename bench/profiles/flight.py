"""The seeded `flight` profile: a day's use of a primary flight control actuator.

Phases (position mode, nut position set-points; `Profile.phases` names them):

1. ``ground-test``: the thesis' pre-flight ground test, the HUMS's maneuver (section
   6.4.2): a +-0.5 mm, 2 Hz sine for four periods (2 s), exactly the `sine` profile.
2. ``take-off``: a settle, then the rotation (a smooth move to +8 mm x severity held 2 s),
   then the climb trim (+3 mm) with light turbulence.
3. ``cruise``: trim (+2 mm) with turbulence: the "small, fast motions from gusts and
   stabilisation" the thesis blames for the wear: seeded coloured noise (white noise
   through a 2nd-order Butterworth low-pass at 3 Hz, standard deviation
   ``turbulence_m`` x severity).
4. ``manoeuvres``: seeded doublets (a move to +-a, to -+a, back; a up to 8 mm x severity,
   held 0.5-2 s each way) on the trim, with the cruise turbulence.
5. ``landing``: approach with stronger turbulence (x1.5), the flare (+6 mm x severity),
   then the surface back to neutral on the ground.

Phase lengths: 2 s of ground test, then 20 %, 40 %, 25 % and 15 % of the rest, 60 s in
all by default. A flight shorter than 30 s (`MIN_DURATION_S`, where every phase has room
for its moves) is the start of a 30 s one: `bench run flight --duration 2` flies the
ground test alone.

Every move is a raised-cosine transition no faster than the nut's 50 mm/s cruise speed
(eq. 5.33) at the largest severity allowed (3); the turbulence is not limited (at
severity 3 its fastest samples ask for about 100 mm/s, and the actuator rate-limits, as a
real one would). Set-points are computed on a 1 kHz grid
when the profile is made and interpolated, so the bus ECU and the in-process harness get
the same numbers for the same seed.
"""

from __future__ import annotations

import math

import numpy as np

from bench import BenchError
from bench.profiles.setpoints import Profile
from bench.signals.trace import MODE_POSITION

GROUND_TEST_S = 2.0          # four periods of the 2 Hz ground-test sine
GROUND_AMPLITUDE_M = 0.5e-3
GROUND_FREQUENCY_HZ = 2.0
FRACTIONS = (("take-off", 0.2), ("cruise", 0.4), ("manoeuvres", 0.25), ("landing", 0.15))
MIN_DURATION_S = 30.0        # every phase long enough for its moves (one doublet at least)
TURBULENCE_CUTOFF_HZ = 3.0
MAX_SEVERITY = 3.0
GRID_S = 1e-3


def _blend(t: np.ndarray, t0: float, dur: float, a: float, b: float) -> np.ndarray:
    """a before t0, b after t0 + dur, a raised cosine between."""
    s = np.clip((t - t0) / dur, 0.0, 1.0)
    return a + (b - a) * 0.5 * (1.0 - np.cos(math.pi * s))


def _turbulence(n: int, std_m: float, rng: np.random.Generator) -> np.ndarray:
    """`n` samples (1 kHz) of coloured noise with standard deviation `std_m`."""
    if n == 0 or std_m == 0.0:
        return np.zeros(n)
    from scipy import signal  # here, not at the top: scipy.signal costs every `bench run` ~0.5 s

    b, a = signal.butter(2, TURBULENCE_CUTOFF_HZ, fs=1.0 / GRID_S)
    settle = int(2.0 / GRID_S)                       # drop the filter's start-up
    y = signal.lfilter(b, a, rng.standard_normal(n + settle))[settle:]
    sd = float(np.std(y))
    return y * (std_m / sd) if sd > 0 else y


def _taper(t: np.ndarray, t0: float, t1: float, ramp: float = 0.5) -> np.ndarray:
    """1 inside [t0 + ramp, t1 - ramp], raised-cosine ramps to 0 at t0 and t1."""
    return _blend(t, t0, ramp, 0.0, 1.0) * _blend(t, t1 - ramp, ramp, 1.0, 0.0)


def flight_setpoints(duration_s: float, severity: float, turbulence_m: float,
                     seed: int) -> tuple[np.ndarray, tuple[tuple[str, float, float], ...]]:
    """The position set-points on the 1 kHz grid and the phases (see module docstring)."""
    # long: one phase after the other on shared arrays, in the order they are flown
    n = int(round(duration_s / GRID_S)) + 1
    t = np.arange(n) * GRID_S
    rng = np.random.default_rng([int(seed), 31])
    phases = [("ground-test", 0.0, GROUND_TEST_S)]
    rest = duration_s - GROUND_TEST_S
    t0 = GROUND_TEST_S
    for name, frac in FRACTIONS:
        phases.append((name, t0, t0 + frac * rest))
        t0 += frac * rest
    (_, g0, g1), (_, to0, to1), (_, cr0, cr1), (_, mn0, mn1), (_, ld0, ld1) = phases
    x = np.where(t < g1, GROUND_AMPLITUDE_M * np.sin(2 * math.pi * GROUND_FREQUENCY_HZ * t),
                 0.0)
    # take-off: settle 10 %, rotate (1 s), hold 2 s, to climb trim (1 s)
    a_rot, trim_climb, trim = 8e-3 * severity, 3e-3, 2e-3
    dto = to1 - to0
    tr0 = to0 + 0.1 * dto
    x += _blend(t, tr0, 1.0, 0.0, a_rot) * (t >= to0)
    x += _blend(t, tr0 + 3.0, 1.0, 0.0, trim_climb - a_rot) * (t >= to0)
    # from the climb trim to the cruise trim at the start of the cruise
    x += _blend(t, cr0, 1.0, 0.0, trim - trim_climb) * (t >= to0)
    # manoeuvres: doublets on the trim
    k = mn0 + 0.5
    while True:
        half = float(rng.uniform(0.5, 2.0))
        amp = float(rng.uniform(0.3, 1.0)) * 8e-3 * severity * float(rng.choice([-1.0, 1.0]))
        if k + 2 * half + 4.5 > mn1:
            half = (mn1 - k - 4.5) / 2.0      # the last doublet shortened to fit
            if half < 0.5:
                break
        x += _blend(t, k, 1.0, 0.0, amp) + _blend(t, k + 1.0 + half, 2.0, 0.0, -2 * amp) \
            + _blend(t, k + 3.0 + 2 * half, 1.0, 0.0, amp)
        k += 2 * half + 5.0
    # landing: flare at 40 %, back to neutral on the ground at 70 %
    dl = ld1 - ld0
    flare, ground = ld0 + 0.4 * dl, ld0 + 0.7 * dl
    x += _blend(t, flare, 1.0, 0.0, 6e-3 * severity - trim) * (t >= ld0)
    x += _blend(t, ground, 1.0, 0.0, -6e-3 * severity) * (t >= ld0)
    # turbulence: light in the climb, full in cruise and manoeuvres, x1.5 on approach
    turb = _turbulence(n, turbulence_m * severity, rng)
    gain = (0.5 * _taper(t, tr0 + 4.0, cr0) + _taper(t, cr0, mn1)
            + 1.5 * _taper(t, ld0, min(ground, ld1)))
    x += turb * gain
    return x, tuple(phases)


def flight(duration_s: float = 60.0, severity: float = 1.0, turbulence_m: float = 0.3e-3,
           seed: float = 1) -> Profile:
    """A seeded flight (module docstring): ground test, take-off, cruise with turbulence,
    manoeuvres, landing; `severity` scales the moves and the turbulence (0-3)."""
    if not 0.0 < severity <= MAX_SEVERITY:
        raise BenchError(f"profile 'flight': severity must be > 0 and <= {MAX_SEVERITY:g}, "
                         f"got {severity:g}")
    if turbulence_m < 0.0 or turbulence_m > 2e-3:
        raise BenchError(f"profile 'flight': turbulence_m must be in [0, 0.002] m, got "
                         f"{turbulence_m:g}")
    if seed != int(seed) or seed < 0:
        raise BenchError(f"profile 'flight': seed must be an integer >= 0, got {seed:g}")
    # shorter than a whole flight: the start of a MIN_DURATION_S one (`--duration 2` is
    # the ground test alone)
    x, phases = flight_setpoints(max(duration_s, MIN_DURATION_S), severity, turbulence_m,
                                 int(seed))
    phases = tuple((n, t0, min(t1, duration_s)) for n, t0, t1 in phases if t0 < duration_s)
    grid = np.arange(len(x)) * GRID_S

    def pos(t: np.ndarray) -> np.ndarray:
        return np.interp(t, grid, x)

    return Profile("flight", MODE_POSITION, duration_s, pos,
                   lambda t: np.zeros_like(t, dtype=float),
                   dict(duration_s=duration_s, severity=severity, turbulence_m=turbulence_m,
                        seed=int(seed)),
                   fundamental_hz=GROUND_FREQUENCY_HZ, phases=phases)
