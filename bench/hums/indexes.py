"""HUMS indexes of thesis section 6.2, from traces (real vs nominal), whole-run and online.

With x the real (measured, LVDT) nut position, i the real (measured) motor current and
x_N, i_N the monitoring model's (nominal) ones, over a window of duration T:

- mean error (eq. 6.4):  |e| = 1/T int |x_N - x| dt                                (m)
- position fidelity (eq. 6.5):  Cp = int x_N x dt / int x^2 dt                      (-)
- current fidelity (eq. 6.6):   Ci = int i_N i dt / int i^2 dt                      (-)
- peak-current ratio (eq. 6.7): ratio = max|i| / max|i_N|                           (-)

Eq. 6.5-6.6 print the integral of a pointwise ratio, which diverges where x or i cross
zero; the reading used here is the ratio of integrals (docs/design.md), which is 1 in
nominal conditions, > 1 (Cp) when the real nut moves less than the nominal one and < 1 (Ci)
when the real motor needs more current. Integrals over uniformly sampled windows are sums
(the dt cancels in the ratios).

- current spectrum (eq. 6.3): one-sided amplitude spectrum of a windowed rfft, calibrated
  so a sine of amplitude A reads A at its line (`amplitude_spectrum`); harmonic features
  are the amplitudes of the command frequency f0 and its multiples, each read from the
  energy of its main lobe so they hold off-bin too (`harmonic_amplitudes`).

Beyond the thesis, from signals an actuator has (encoder angle and speed, LVDT):
- lost motion (m): the hysteresis between the encoder travel (motor angle x tau p / 2 pi
  through the nominal LVDT dynamics) and the LVDT reading, split by the direction of
  motion: median while moving forward minus median while moving back. A rigid screw
  gives 0; backlash b gives about b / (cos alpha sin beta) once preload no longer takes
  it up.
- reversal dead time (s): per command period, the time the motor moves (|encoder speed| >
  10 % of its peak) while the nut does not (|LVDT speed| < 5 % of its peak), real minus
  nominal.

`period_indexes` yields all of them for each command period of a long trace (the RUL run,
a live bus run); `OnlineHums` does the same from samples pushed as they arrive.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.trace import Trace

N_HARMONICS = 5
POSITION_SIGNALS = ("position_m",)
CURRENT_SIGNALS = ("current_a",)
LOST_MOTION_SIGNALS = ("motor_angle_rad", "motor_speed_rad_s", "position_m")


# --- array-level indexes (nominal first, real second) ---------------------------------------

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


# --- spectrum (eq. 6.3) ----------------------------------------------------------------------

def _window(name: str, n: int) -> np.ndarray:
    if name in ("hann", "hanning"):     # periodic Hann: exact on-bin for the DFT
        return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n) if n > 1 else np.ones(n)
    if name in ("rect", "rectangular", "boxcar", "none"):
        return np.ones(n)
    if name == "flattop":
        from scipy.signal import windows
        return windows.flattop(n, sym=False)
    raise BenchError(f"unknown window {name!r} (hann, rect, flattop)")


def amplitude_spectrum(y: np.ndarray, dt: float, window: str = "hann",
                       detrend: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum of `y` sampled every `dt` s (eq. 6.3, numpy rfft).

    Calibrated by the window's coherent gain: a sine of amplitude A whose frequency falls
    on a bin reads A at that bin (between bins, the Hann window reads down to 0.85 A at
    the peak; `harmonic_amplitudes` reads the lobe energy instead). With `detrend` the
    mean is removed first (it is reported by no bin). Returns (frequencies Hz, amplitudes
    in the unit of y).
    """
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or len(y) < 4:
        raise BenchError("a spectrum needs a 1-D signal of at least 4 samples")
    if not np.isfinite(y).all():
        raise BenchError("the signal has non-finite samples; cannot compute its spectrum")
    if detrend:
        y = y - y.mean()
    w = _window(window, len(y))
    spec = np.abs(np.fft.rfft(y * w)) / w.sum()
    spec[1:] *= 2.0
    if len(y) % 2 == 0:
        spec[-1] /= 2.0          # the Nyquist bin has no mirror
    return np.fft.rfftfreq(len(y), dt), spec


def harmonic_amplitudes(y: np.ndarray, dt: float, f0: float, n: int = N_HARMONICS,
                        window: str = "hann") -> np.ndarray:
    """Amplitudes of f0, 2 f0, ..., n f0 in `y` (unit of y), NaN above Nyquist.

    Each is sqrt(4 sum|X_k|^2 / (N sum w^2)) over the bins nearer h f0 than half the
    spacing of the harmonics (and within the window's main lobe, +-2 bins for Hann):
    Parseval's reading of a sine's amplitude, which does not depend on where the line
    falls between bins once the harmonics are at least 4 bins apart (a Hann window of at
    least four command periods, as the thesis' FFT; within one period use "rect").
    """
    y = np.asarray(y, dtype=float)
    if not (math.isfinite(f0) and f0 > 0):
        raise BenchError("harmonic amplitudes need a command frequency f0 > 0 Hz")
    if len(y) < 4 or not np.isfinite(y).all():
        raise BenchError("harmonic amplitudes need a finite signal of at least 4 samples")
    N = len(y)
    y = y - y.mean()
    w = _window(window, N)
    X = np.fft.rfft(y * w)
    df = 1.0 / (N * dt)
    bins_per_h = f0 / df
    lobe = {"hann": 2, "hanning": 2, "flattop": 5}.get(window, 1)
    if bins_per_h < 1.0 - 1e-9:
        raise BenchError(f"the window ({N * dt:.3g} s) is shorter than one period of "
                         f"{f0:g} Hz: no harmonic can be resolved")
    norm = N * float(np.sum(w * w))
    out = np.full(n, np.nan)
    k = np.arange(len(X))
    reach = min(lobe + 1.0, 0.5 * bins_per_h)   # each harmonic's own share of the bins
    for h in range(1, n + 1):
        c = h * bins_per_h
        if c + reach >= len(X) - 1:
            break
        sel = (np.abs(k - c) < reach) & (k >= 1)
        out[h - 1] = math.sqrt(4.0 * float(np.sum(np.abs(X[sel]) ** 2)) / norm)
    return out


# --- lost motion and reversal dead time -------------------------------------------------------

@dataclass(frozen=True)
class Kinematics:
    """Nominal screw kinematics and LVDT dynamics used by lost motion (from PlantParams)."""
    travel_per_motor_rad_m: float = 0.25 * 5e-3 / (2 * math.pi)
    lvdt_natural_rad_s: float = 1256.0
    lvdt_damping: float = 0.8

    @classmethod
    def from_plant(cls, params: Any = None) -> Kinematics:
        from plant_rt.params import PlantParams
        p = params or PlantParams()
        return cls(p.reducer.ratio * p.screw.lead_m / (2 * math.pi),
                   p.sensors.lvdt_natural_rad_s, p.sensors.lvdt_damping)


class MotionStream:
    """Causal, streaming signals behind lost motion and dead time.

    push(motor angle, LVDT, motor speed) -> (d, w_s, v_s):
      d    encoder travel through the nominal LVDT dynamics minus the LVDT reading (m);
           the encoder travel is (angle - angle_0) tau p / 2 pi + LVDT_0, filtered by
           wn^2 / (s^2 + 2 zeta wn s + wn^2) discretised exactly for piecewise-linear
           input (first-order hold), starting settled;
      w_s  motor speed, moving average over `smooth` samples (rad/s);
      v_s  LVDT speed (backward difference), moving average over `smooth` samples (m/s).
    Everything is causal and carries its state, so pushing a trace in pieces gives the
    same result as pushing it whole (the online indicator equals the offline one).
    """

    def __init__(self, dt: float, kin: Kinematics | None = None, smooth: int = 10) -> None:
        from scipy.signal import cont2discrete
        self.kin = kin or Kinematics()
        wn, z = self.kin.lvdt_natural_rad_s, self.kin.lvdt_damping
        b, a, _ = cont2discrete(([wn * wn], [1.0, 2.0 * z * wn, wn * wn]), dt, method="foh")
        self.b = np.ravel(b)
        self.a = np.ravel(a)
        self.dt = dt
        self.smooth = max(1, int(smooth))
        self._zi: np.ndarray | None = None
        self._a0 = 0.0
        self._x0 = 0.0
        self._last_pos = math.nan
        self._zw: np.ndarray | None = None
        self._zv: np.ndarray | None = None

    def push(self, angle: np.ndarray, pos: np.ndarray, speed: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        from scipy.signal import lfilter, lfilter_zi
        angle = np.asarray(angle, dtype=float)
        pos = np.asarray(pos, dtype=float)
        speed = np.asarray(speed, dtype=float)
        if len(angle) == 0:
            e = np.zeros(0)
            return e, e, e
        if self._zi is None:
            self._a0, self._x0 = float(angle[0]), float(pos[0])
            self._zi = lfilter_zi(self.b, self.a) * self._x0
            k = np.ones(self.smooth) / self.smooth
            self._zw = lfilter_zi(k, [1.0]) * float(speed[0])
            self._zv = lfilter_zi(k, [1.0]) * 0.0
            self._last_pos = float(pos[0])
        x = (angle - self._a0) * self.kin.travel_per_motor_rad_m + self._x0
        enc, self._zi = lfilter(self.b, self.a, x, zi=self._zi)
        k = np.ones(self.smooth) / self.smooth
        w_s, self._zw = lfilter(k, [1.0], speed, zi=self._zw)
        v = np.diff(np.concatenate(([self._last_pos], pos))) / self.dt
        self._last_pos = float(pos[-1])
        v_s, self._zv = lfilter(k, [1.0], v, zi=self._zv)
        return enc - pos, w_s, v_s


def lost_motion_from(d: np.ndarray, speed: np.ndarray, speed_fraction: float = 0.2) -> float:
    """median(d | moving forward) - median(d | moving back), leaving out samples with
    |motor speed| below `speed_fraction` of its peak in the window; NaN unless the motor
    moves both ways."""
    pk = float(np.max(np.abs(speed))) if len(speed) else 0.0
    if not pk > 0:
        return math.nan
    fwd, back = speed > speed_fraction * pk, speed < -speed_fraction * pk
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


def motion_signals(trace: Trace, kin: Kinematics | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(d, w_s, v_s) of `MotionStream` over the whole trace."""
    trace.require(LOST_MOTION_SIGNALS, "the lost-motion and dead-time indexes")
    return MotionStream(trace.dt, kin).push(trace["motor_angle_rad"], trace["position_m"],
                                            trace["motor_speed_rad_s"])


def lost_motion(trace: Trace, kin: Kinematics | None = None) -> float:
    """Lost motion between motor and nut over the whole trace (m); see the module doc."""
    d, _, _ = motion_signals(trace, kin)
    return lost_motion_from(d, trace["motor_speed_rad_s"])


def stall_time(trace: Trace, kin: Kinematics | None = None) -> float:
    """Time (s) the motor moves while the nut stands, over the whole trace."""
    _, w_s, v_s = motion_signals(trace, kin)
    return stall_time_from(w_s, v_s, trace.dt)


# --- lost samples: bridged when short, else the indexes that need them are unavailable ----

BRIDGE_MAX_SAMPLES = 5
"""Longest run of missing samples (lost SYNCs, missing frames, NaN rows) that is bridged
by interpolation: 5 ms at 1 kHz, 1 % of the 2 Hz command period and 1/6 of the period of
the 15th harmonic (30 Hz), the highest line an index reads; over such a run a linear
bridge of a sine at 30 Hz is off by at most 15 % of that line's (small) amplitude, on
5 samples of the thousands an index integrates."""
BRIDGE_MAX_FRACTION = 0.02
"""Largest share of a signal's samples that may be bridged in all (as `bench gap`)."""

INDEX_SIGNALS: dict[str, tuple[str, ...]] = {
    "mean_error_m": POSITION_SIGNALS, "cp": POSITION_SIGNALS,
    "ci": CURRENT_SIGNALS, "ci_harmonic": CURRENT_SIGNALS, "peak_ratio": CURRENT_SIGNALS,
    "current_rms_a": CURRENT_SIGNALS, "harmonics_a": CURRENT_SIGNALS,
    "friction_current_a": CURRENT_SIGNALS + ("motor_speed_rad_s",),
    "lost_motion_m": LOST_MOTION_SIGNALS, "dead_time_s": LOST_MOTION_SIGNALS,
}
"""The measured signals each index of `Indexes` reads."""
HOLD_SIGNALS = ("mode", "status_word", "run")
"""Signals bridged by holding the previous value (states, not samples of a motion)."""


def missing_runs(y: np.ndarray) -> list[tuple[int, int]]:
    """(first index, length) of each run of non-finite samples of `y`."""
    bad = ~np.isfinite(np.asarray(y, dtype=float))
    if not bad.any():
        return []
    edges = np.diff(np.concatenate(([0], bad.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b - a)) for a, b in zip(starts, ends, strict=True)]


@dataclass
class Gaps:
    """The missing samples of one signal of a trace."""
    column: str
    n: int                           # samples in the trace
    runs: list[tuple[int, int]]      # (first index, length)

    @property
    def missing(self) -> int:
        return sum(k for _, k in self.runs)

    @property
    def longest(self) -> tuple[int, int]:
        return max(self.runs, key=lambda r: r[1])

    @property
    def bridgeable(self) -> bool:
        return (self.longest[1] <= BRIDGE_MAX_SAMPLES
                and self.missing <= BRIDGE_MAX_FRACTION * self.n)

    def describe(self, t: np.ndarray) -> str:
        at, k = self.longest
        return (f"{self.missing} samples missing in {self.column} (longest gap {k} samples "
                f"at t = {float(t[at]):.3f} s; up to {BRIDGE_MAX_SAMPLES} in a row and "
                f"{100 * BRIDGE_MAX_FRACTION:g} % in all can be bridged)")


def signal_gaps(trace: Trace, columns: tuple[str, ...]) -> dict[str, Gaps]:
    """The signals among `columns` with missing samples (a signal missing throughout is
    absent, not a gap)."""
    out = {}
    for c in columns:
        if c in trace and np.isfinite(trace[c]).any():
            runs = missing_runs(trace[c])
            if runs:
                out[c] = Gaps(c, len(trace), runs)
    return out


def bridge(trace: Trace, gaps: dict[str, Gaps]) -> Trace:
    """A copy of `trace` with the missing samples of the signals in `gaps` filled: linear
    interpolation in time (HOLD_SIGNALS: the previous value), the nearest value at the
    ends. Long gaps are filled too, so that no NaN reaches a filter or a spectrum; the
    caller marks what they make unavailable (`mark_unavailable`)."""
    cols = dict(trace.columns)
    t = trace.t
    for c in gaps:
        y = np.asarray(cols[c], dtype=float)
        ok = np.isfinite(y)
        if c in HOLD_SIGNALS:
            idx = np.maximum.accumulate(np.where(ok, np.arange(len(y)), -1))
            first = int(np.argmax(ok))
            y = y[np.where(idx < 0, first, idx)]
        else:
            y = np.interp(t, t[ok], y[ok])
        cols[c] = y
    return Trace(cols, dict(trace.meta))


def mark_unavailable(ix: Indexes, blocked: dict[str, str],
                     drive: tuple[str, ...] = ()) -> None:
    """Set to NaN (and explain in ``ix.unavailable``) every index that reads a signal in
    `blocked` (signal -> why); a blocked `drive` signal (the set-points of the monitoring
    model) makes every index unavailable."""
    why_all = next((blocked[c] for c in drive if c in blocked), None)
    for name, needs in INDEX_SIGNALS.items():
        why = why_all or next((blocked[c] for c in needs if c in blocked), None)
        if why is None:
            continue
        ix.unavailable[name] = f"not available: {why}"
        if name == "harmonics_a":
            ix.harmonics_a = []
        else:
            setattr(ix, name, math.nan)
    if why_all is not None:
        for name in ("nominal_current_rms_a", "nominal_lost_motion_m",
                     "nominal_friction_current_a"):
            setattr(ix, name, math.nan)
        ix.nominal_harmonics_a = []


# --- trace-level comparison ---------------------------------------------------------------------

@dataclass
class Indexes:
    """Indexes of one window (whole run or one command period). NaN = not computable."""
    t_start_s: float
    t_end_s: float
    mean_error_m: float = math.nan
    cp: float = math.nan
    ci: float = math.nan
    peak_ratio: float = math.nan
    current_rms_a: float = math.nan
    nominal_current_rms_a: float = math.nan
    harmonics_a: list[float] = field(default_factory=list)
    nominal_harmonics_a: list[float] = field(default_factory=list)
    lost_motion_m: float = math.nan
    nominal_lost_motion_m: float = math.nan
    dead_time_s: float = math.nan
    ci_harmonic: float = math.nan
    friction_current_a: float = math.nan
    nominal_friction_current_a: float = math.nan
    extra: dict[str, float] = field(default_factory=dict)
    unavailable: dict[str, str] = field(default_factory=dict)   # index -> why it is NaN

    @property
    def t_mid_s(self) -> float:
        return 0.5 * (self.t_start_s + self.t_end_s)

    @property
    def harmonic_distortion(self) -> float:
        """sqrt(sum of harmonics 2..n squared) / fundamental, real current (-)."""
        h = np.asarray(self.harmonics_a, dtype=float)
        if len(h) < 2 or not h[0] > 0:
            return math.nan
        return float(np.sqrt(np.nansum(h[1:] ** 2)) / h[0])

    @property
    def nominal_harmonic_distortion(self) -> float:
        h = np.asarray(self.nominal_harmonics_a, dtype=float)
        if len(h) < 2 or not h[0] > 0:
            return math.nan
        return float(np.sqrt(np.nansum(h[1:] ** 2)) / h[0])

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["harmonic_distortion"] = self.harmonic_distortion
        d["nominal_harmonic_distortion"] = self.nominal_harmonic_distortion
        return d


def _fundamental(trace: Trace, f0: float | None) -> float:
    if f0 is not None:
        return float(f0)
    v = trace.meta.get("fundamental_hz")
    try:
        return float(v) if v is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


def _aligned(real: Trace, nominal: Trace) -> None:
    if len(real) != len(nominal):
        raise BenchError(f"real and nominal traces differ in length ({len(real)} vs "
                         f"{len(nominal)} samples); build the nominal with "
                         "bench.hums.monitor.nominal_for(real)")


def compare(real: Trace, nominal: Trace, f0_hz: float | None = None,
            n_harmonics: int = N_HARMONICS, need: tuple[str, ...] = ("position", "current"),
            window: str = "hann", kin: Kinematics | None = None) -> Indexes:
    """All indexes of `real` against `nominal` over the whole window.

    `need` names the groups the caller requires ("position": |e| and Cp; "current": Ci,
    peak ratio and harmonics); a missing signal of a required group is a BenchError, the
    other groups are computed when their signals are there and NaN otherwise. Harmonics
    need the command frequency (`f0_hz` or the trace's ``fundamental_hz`` metadata).
    """
    _aligned(real, nominal)
    for g in need:
        if g not in ("position", "current", "lost_motion"):
            raise BenchError(f"unknown index group {g!r}")
    if "position" in need:
        real.require(POSITION_SIGNALS, "the position indexes (eq. 6.4-6.5)")
    if "current" in need:
        real.require(CURRENT_SIGNALS, "the current indexes (eq. 6.6-6.7)")
    if "lost_motion" in need:
        real.require(LOST_MOTION_SIGNALS, "the lost-motion index")
    t = real.t
    out = Indexes(float(t[0]), float(t[-1] + real.dt) if len(t) > 1 else float(t[0]))
    if _has(real, POSITION_SIGNALS):
        xn, x = nominal["position_m"], real["position_m"]
        out.mean_error_m = mean_error(xn, x)
        out.cp = cp(xn, x)
    if _has(real, CURRENT_SIGNALS):
        i_n, i = nominal["current_a"], real["current_a"]
        out.ci = ci(i_n, i)
        out.peak_ratio = peak_ratio(i_n, i)
        out.current_rms_a = float(np.sqrt(np.mean(i * i)))
        out.nominal_current_rms_a = float(np.sqrt(np.mean(i_n * i_n)))
        f0 = _fundamental(real, f0_hz)
        if math.isfinite(f0) and f0 > 0 and f0 * len(real) * real.dt >= 1.0 - 1e-9:
            out.ci_harmonic = ci_harmonic(i_n, i, int(round(1.0 / (f0 * real.dt))))
            out.harmonics_a = harmonic_amplitudes(i, real.dt, f0, n_harmonics, window).tolist()
            out.nominal_harmonics_a = harmonic_amplitudes(i_n, real.dt, f0, n_harmonics,
                                                          window).tolist()
    if _has(real, CURRENT_SIGNALS + ("motor_speed_rad_s",)):
        out.friction_current_a = friction_current(real["current_a"], real["motor_speed_rad_s"])
        out.nominal_friction_current_a = friction_current(nominal["current_a"],
                                                          nominal["motor_speed_rad_s"])
    if _has(real, LOST_MOTION_SIGNALS) and _has(nominal, LOST_MOTION_SIGNALS):
        d, w_s, v_s = motion_signals(real, kin)
        dn, wn_s, vn_s = motion_signals(nominal, kin)
        out.lost_motion_m = lost_motion_from(d, real["motor_speed_rad_s"])
        out.nominal_lost_motion_m = lost_motion_from(dn, nominal["motor_speed_rad_s"])
        out.dead_time_s = (stall_time_from(w_s, v_s, real.dt)
                           - stall_time_from(wn_s, vn_s, real.dt))
    return out


def _has(trace: Trace, names: tuple[str, ...]) -> bool:
    return all(n in trace and np.isfinite(trace[n]).any() for n in names)


# --- per command period (online indicators) ---------------------------------------------------

def _slice(trace: Trace, sl: slice) -> Trace:
    return Trace({k: v[sl] for k, v in trace.columns.items()}, trace.meta)


def period_indexes(real: Trace, nominal: Trace, period_s: float | None = None,
                   t0_s: float | None = None, n_harmonics: int = N_HARMONICS,
                   kin: Kinematics | None = None) -> Iterator[Indexes]:
    """Indexes of each whole command period of `real` against `nominal`.

    `period_s` defaults to 1 / the trace's ``fundamental_hz``. Periods start at `t0_s`
    (default: the first sample). Within one period the harmonics use a rectangular
    window (the period holds exactly one cycle of f0 and of every harmonic). Lost motion
    and dead time use causal filters run over the whole trace, so they equal what
    `OnlineHums` reports from the same samples pushed live.
    """
    _aligned(real, nominal)
    real.require(CURRENT_SIGNALS + POSITION_SIGNALS, "the per-period HUMS indexes")
    if period_s is None:
        f0 = _fundamental(real, None)
        if not (math.isfinite(f0) and f0 > 0):
            raise BenchError("per-period indexes need the command period: pass period_s "
                             "or a trace with fundamental_hz metadata")
        period_s = 1.0 / f0
    dt = real.dt
    m = int(round(period_s / dt))
    if m < 8:
        raise BenchError(f"a command period of {period_s:g} s holds fewer than 8 samples")
    t = real.t
    k0 = 0 if t0_s is None else int(np.searchsorted(t, t0_s - 0.5 * dt))
    mot = None
    if _has(real, LOST_MOTION_SIGNALS) and _has(nominal, LOST_MOTION_SIGNALS):
        mot = (motion_signals(real, kin), motion_signals(nominal, kin))
    while k0 + m <= len(t):
        sl = slice(k0, k0 + m)
        ms = None if mot is None else tuple(tuple(a[sl] for a in grp) for grp in mot)
        yield _one_period(_slice(real, sl), _slice(nominal, sl), period_s, n_harmonics, ms)
        k0 += m


def _one_period(r: Trace, nm: Trace, period_s: float, n_harmonics: int,
                mot: Any) -> Indexes:
    x, xn = r["position_m"], nm["position_m"]
    i, i_n = r["current_a"], nm["current_a"]
    out = Indexes(float(r.t[0]), float(r.t[0] + period_s),
                  mean_error_m=mean_error(xn, x), cp=cp(xn, x), ci=ci(i_n, i),
                  peak_ratio=peak_ratio(i_n, i),
                  current_rms_a=float(np.sqrt(np.mean(i * i))),
                  nominal_current_rms_a=float(np.sqrt(np.mean(i_n * i_n))))
    f0 = 1.0 / period_s
    out.harmonics_a = harmonic_amplitudes(i, r.dt, f0, n_harmonics, "rect").tolist()
    out.nominal_harmonics_a = harmonic_amplitudes(i_n, r.dt, f0, n_harmonics, "rect").tolist()
    out.ci_harmonic = ci_harmonic(i_n, i, len(i))
    if "motor_speed_rad_s" in r and np.isfinite(r["motor_speed_rad_s"]).all():
        out.friction_current_a = friction_current(i, r["motor_speed_rad_s"])
        out.nominal_friction_current_a = friction_current(i_n, nm["motor_speed_rad_s"])
    if mot is not None:
        (d, w_s, v_s), (dn, wn_s, vn_s) = mot
        out.lost_motion_m = lost_motion_from(d, r["motor_speed_rad_s"])
        out.nominal_lost_motion_m = lost_motion_from(dn, nm["motor_speed_rad_s"])
        out.dead_time_s = stall_time_from(w_s, v_s, r.dt) - stall_time_from(wn_s, vn_s, r.dt)
    return out


def as_table(rows: list[Indexes]) -> dict[str, np.ndarray]:
    """Per-period indexes as columns: t_start_s, t_mid_s, ci, cp, mean_error_m,
    peak_ratio, current RMS, harmonic distortion, lost motion, dead time, h1_a.. and
    nominal_h1_a.. (current harmonic amplitudes, A)."""
    if not rows:
        return {}
    scalars = ("t_start_s", "t_mid_s", "ci", "cp", "mean_error_m", "peak_ratio",
               "current_rms_a", "nominal_current_rms_a", "harmonic_distortion",
               "nominal_harmonic_distortion", "lost_motion_m", "nominal_lost_motion_m",
               "dead_time_s", "ci_harmonic", "friction_current_a",
               "nominal_friction_current_a")
    cols: dict[str, np.ndarray] = {k: np.array([float(getattr(r, k)) for r in rows])
                                   for k in scalars}
    nh = max(len(r.harmonics_a) for r in rows)
    for h in range(nh):
        cols[f"h{h + 1}_a"] = np.array([r.harmonics_a[h] if h < len(r.harmonics_a)
                                        else math.nan for r in rows])
        cols[f"nominal_h{h + 1}_a"] = np.array(
            [r.nominal_harmonics_a[h] if h < len(r.nominal_harmonics_a) else math.nan
             for r in rows])
    return cols


class OnlineHums:
    """Per-command-period indexes from samples pushed as they arrive (live bus runs).

    Push SYNC-rate samples (a dict of equal-length arrays, or scalars, with the measured
    column names); each time a whole command period has arrived, the monitoring model is
    advanced over that period's set-points (its state carries over, so the nominal is the
    one long run's) and the period's `Indexes` are returned. Gives the same numbers as
    `period_indexes` on the whole trace.
    """

    NEED = ("t_s", "setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_a",
            "position_m")

    def __init__(self, period_s: float, position_kp_rad_s_per_m: float | None = None,
                 mparams: Any = None, cparams: Any = None, n_harmonics: int = N_HARMONICS,
                 kin: Kinematics | None = None) -> None:
        from bench.hums.monitor import Monitor, MonitorParams
        self.mparams = mparams or MonitorParams.from_plant()
        self.period_s = float(period_s)
        self.m = int(round(self.period_s / self.mparams.sync_period_s))
        if self.m < 8:
            raise BenchError("the command period must hold at least 8 SYNC periods")
        self.monitor = Monitor(self.mparams, position_kp_rad_s_per_m, cparams)
        self.n_harmonics = n_harmonics
        self.kin = kin
        self._buf: dict[str, list[np.ndarray]] = {}
        self._n = 0
        self._started = False
        self._streams: tuple[MotionStream, MotionStream] | None = None

    def push(self, rows: dict[str, Any]) -> list[Indexes]:
        missing = [k for k in self.NEED if k not in rows]
        if missing:
            raise BenchError(f"online HUMS needs the signal(s) {', '.join(missing)}")
        arrs = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in rows.items()}
        n = len(arrs["t_s"])
        for k, v in arrs.items():
            if len(v) != n:
                raise BenchError(f"online HUMS: column {k!r} has {len(v)} samples, t_s {n}")
        if not self._started:
            x0 = float(arrs["position_m"][0])
            self.monitor.x0_m = x0 if abs(x0) >= 20e-6 else 0.0
            self.monitor.reset()
            if all(k in arrs for k in LOST_MOTION_SIGNALS):
                dt = self.mparams.sync_period_s
                self._streams = (MotionStream(dt, self.kin), MotionStream(dt, self.kin))
            self._started = True
        for k, v in arrs.items():
            self._buf.setdefault(k, []).append(v)
        self._n += n
        out = []
        while self._n >= self.m:
            cols = {k: np.concatenate(v) for k, v in self._buf.items()}
            now = {k: v[:self.m] for k, v in cols.items()}
            self._buf = {k: [v[self.m:]] for k, v in cols.items()}
            self._n -= self.m
            out.append(self._period(now))
        return out

    def _period(self, cols: dict[str, np.ndarray]) -> Indexes:
        from bench.hums.monitor import _columns
        mon = self.monitor.run(cols["setpoint_position_m"], cols["setpoint_speed_rad_s"],
                               cols["mode"])
        nom = Trace(_columns(cols["t_s"], cols["setpoint_position_m"],
                             cols["setpoint_speed_rad_s"], cols["mode"], mon))
        real = Trace(dict(cols))
        mot = None
        if self._streams is not None:
            a, b = self._streams
            mot = (a.push(real["motor_angle_rad"], real["position_m"],
                          real["motor_speed_rad_s"]),
                   b.push(nom["motor_angle_rad"], nom["position_m"],
                          nom["motor_speed_rad_s"]))
        return _one_period(real, nom, self.period_s, self.n_harmonics, mot)
