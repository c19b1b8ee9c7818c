"""The HUMS index formulas of thesis section 6.2 on arrays (nominal first, real second).

With x the real (measured, LVDT) nut position, i the real motor current and x_N, i_N the
monitoring model's (nominal) ones, over a window of duration T:

- mean error (eq. 6.4):  |e| = 1/T int |x_N - x| dt                                (m)
- position fidelity (eq. 6.5):  Cp = int x_N x dt / int x^2 dt                      (-)
- current fidelity (eq. 6.6):   Ci = int i_N i dt / int i^2 dt                      (-)
- peak-current ratio (eq. 6.7): ratio = max|i| / max|i_N|                           (-)

Eq. 6.5-6.6 print the integral of a pointwise ratio, which diverges where x or i cross
zero; the reading used here is the ratio of integrals (docs/hums.md), which is 1 in
nominal conditions, > 1 (Cp) when the real nut moves less than the nominal one and < 1 (Ci)
when the real motor needs more current. Integrals over uniformly sampled windows are sums
(the dt cancels in the ratios).

Beyond the thesis: the harmonic Ci, the friction current, and the lost-motion and
reversal dead-time readings of the signals `bench.hums.motion` streams.
"""

from __future__ import annotations

import math

import numpy as np

from bench import BenchError
from bench.signals import estimators as E

POSITION_SIGNALS = ("position_m",)
CURRENT_SIGNALS = ("current_a",)
LOST_MOTION_SIGNALS = ("motor_angle_rad", "motor_speed_rad_s", "position_m")


def _check_pair(a: np.ndarray, b: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise BenchError(f"{what}: nominal and real signals must be 1-D of equal length "
                         f"(got {a.shape} and {b.shape})")
    if len(a) == 0:
        raise BenchError(f"{what}: empty window")
    return a, b


def mean_error(x_nominal: np.ndarray, x_real: np.ndarray) -> float:
    """Eq. 6.4: mean |x_N - x| over the window (m)."""
    xn, x = _check_pair(x_nominal, x_real, "mean error")
    return float(np.mean(np.abs(xn - x)))


def fidelity(nominal: np.ndarray, real: np.ndarray) -> float:
    """int(nominal real) / int(real^2): eq. 6.5-6.6 read as a ratio of integrals."""
    a, b = _check_pair(nominal, real, "fidelity coefficient")
    den = float(np.dot(b, b))
    if not den > 0:
        return math.nan
    return float(np.dot(a, b) / den)


def cp(x_nominal: np.ndarray, x_real: np.ndarray) -> float:
    """Eq. 6.5, position fidelity coefficient Cp = int x_N x / int x^2."""
    return fidelity(x_nominal, x_real)


def ci(i_nominal: np.ndarray, i_real: np.ndarray) -> float:
    """Eq. 6.6, current fidelity coefficient Ci = int i_N i / int i^2."""
    return fidelity(i_nominal, i_real)


def peak_ratio(i_nominal: np.ndarray, i_real: np.ndarray) -> float:
    """Eq. 6.7, |max|i| / max|i_N||."""
    a, b = _check_pair(i_nominal, i_real, "peak-current ratio")
    pk = float(np.max(np.abs(a)))
    return float(np.max(np.abs(b)) / pk) if pk > 0 else math.nan


def ci_harmonic(i_nominal: np.ndarray, i_real: np.ndarray, period_samples: int,
                n_harmonics: int = 15) -> float:
    """Ci restricted to the command frequency and its first `n_harmonics` multiples:
    sum_h Re(I_N,h conj(I_h)) / sum_h |I_h|^2 over the whole periods of the window.

    By Parseval this is eq. 6.6 (ratio-of-integrals reading) applied to the periodic
    part of both currents; broadband sensor and loop noise outside those lines (most of
    it, up to the 500 Hz Nyquist frequency) no longer biases it. NaN on a window shorter
    than one period."""
    a, b = _check_pair(i_nominal, i_real, "harmonic current fidelity")
    m = int(period_samples)
    n_per = len(a) // m if m > 0 else 0
    if n_per < 1:
        return math.nan
    n = n_per * m
    A = np.fft.rfft(a[:n])
    B = np.fft.rfft(b[:n])
    idx = n_per * np.arange(1, n_harmonics + 1)
    idx = idx[idx < len(B)]
    den = float(np.sum(np.abs(B[idx]) ** 2))
    return float(np.sum((A[idx] * np.conj(B[idx])).real) / den) if den > 0 else math.nan


def friction_current(i: np.ndarray, speed: np.ndarray) -> float:
    """mean(i sign(speed)) (A): the part of the current that pushes against motion.

    On a periodic maneuver the inertial current (in phase with the acceleration) averages
    out against sign(speed), so this is the current that Coulomb and viscous friction cost;
    samples with |speed| below 5 % of its peak are left out (reversals)."""
    i = np.asarray(i, dtype=float)
    w = np.asarray(speed, dtype=float)
    pk = float(np.max(np.abs(w))) if len(w) else 0.0
    if not pk > 0:
        return math.nan
    m = np.abs(w) > 0.05 * pk
    return float(np.mean(i[m] * np.sign(w[m]))) if m.any() else math.nan


def lost_motion_from(d: np.ndarray, speed: np.ndarray, speed_fraction: float = 0.2) -> float:
    """median(d | moving forward) - median(d | moving back), leaving out samples with
    |motor speed| below `speed_fraction` of its peak in the window; NaN unless the motor
    moves both ways."""
    pk = float(np.max(np.abs(speed))) if len(speed) else 0.0
    if not pk > 0:
        return math.nan
    way = E.motion_direction(speed, speed_fraction * pk)
    fwd, back = way > 0, way < 0
    if fwd.sum() < 5 or back.sum() < 5:
        return math.nan
    return float(np.median(d[fwd]) - np.median(d[back]))


def stall_time_from(w_s: np.ndarray, v_s: np.ndarray, dt: float) -> float:
    """Time (s) the motor moves (|w_s| > 10 % of its peak) while the nut does not
    (|v_s| < 5 % of its peak) in the window."""
    wp = float(np.max(np.abs(w_s))) if len(w_s) else 0.0
    vp = float(np.max(np.abs(v_s))) if len(v_s) else 0.0
    if not (wp > 0 and vp > 0):
        return math.nan
    return float(np.sum((np.abs(w_s) > 0.1 * wp) & (np.abs(v_s) < 0.05 * vp)) * dt)
