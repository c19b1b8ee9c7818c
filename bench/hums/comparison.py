"""The HUMS indexes of one window of a real trace against its nominal (`Indexes`, `compare`)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums import formulas as F
from bench.hums.motion import Kinematics, motion_signals
from bench.hums.spectra import N_HARMONICS, harmonic_amplitudes
from bench.signals import estimators as E
from bench.signals.trace import Trace


def distortion(harmonics_a) -> float:
    """sqrt(sum of harmonics 2..n squared) / fundamental (-); NaN without a fundamental."""
    h = np.asarray(harmonics_a, dtype=float)
    if len(h) < 2 or not h[0] > 0:
        return math.nan
    return float(np.sqrt(np.nansum(h[1:] ** 2)) / h[0])

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
        """Harmonic distortion of the real current (`distortion`)."""
        return distortion(self.harmonics_a)

    @property
    def nominal_harmonic_distortion(self) -> float:
        """Harmonic distortion of the nominal current (`distortion`)."""
        return distortion(self.nominal_harmonics_a)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["harmonic_distortion"] = self.harmonic_distortion
        d["nominal_harmonic_distortion"] = self.nominal_harmonic_distortion
        return d


def check_aligned(real: Trace, nominal: Trace) -> None:
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
    check_aligned(real, nominal)
    for g in need:
        if g not in ("position", "current", "lost_motion"):
            raise BenchError(f"unknown index group {g!r}")
    if "position" in need:
        real.require(F.POSITION_SIGNALS, "the position indexes (eq. 6.4-6.5)")
    if "current" in need:
        real.require(F.CURRENT_SIGNALS, "the current indexes (eq. 6.6-6.7)")
    if "lost_motion" in need:
        real.require(F.LOST_MOTION_SIGNALS, "the lost-motion index")
    t = real.t
    out = Indexes(float(t[0]), float(t[-1] + real.dt) if len(t) > 1 else float(t[0]))
    if has_signals(real, F.POSITION_SIGNALS):
        xn, x = nominal["position_m"], real["position_m"]
        out.mean_error_m = F.mean_error(xn, x)
        out.cp = F.cp(xn, x)
    if has_signals(real, F.CURRENT_SIGNALS):
        i_n, i = nominal["current_a"], real["current_a"]
        out.ci = F.ci(i_n, i)
        out.peak_ratio = F.peak_ratio(i_n, i)
        out.current_rms_a = float(np.sqrt(np.mean(i * i)))
        out.nominal_current_rms_a = float(np.sqrt(np.mean(i_n * i_n)))
        f0 = E.fundamental_hz((f0_hz, real.meta.get("fundamental_hz")))
        if math.isfinite(f0) and f0 > 0 and f0 * len(real) * real.dt >= 1.0 - 1e-9:
            out.ci_harmonic = F.ci_harmonic(i_n, i, int(round(1.0 / (f0 * real.dt))))
            out.harmonics_a = harmonic_amplitudes(i, real.dt, f0, n_harmonics, window).tolist()
            out.nominal_harmonics_a = harmonic_amplitudes(i_n, real.dt, f0, n_harmonics,
                                                          window).tolist()
    if has_signals(real, F.CURRENT_SIGNALS + ("motor_speed_rad_s",)):
        out.friction_current_a = F.friction_current(real["current_a"], real["motor_speed_rad_s"])
        out.nominal_friction_current_a = F.friction_current(nominal["current_a"],
                                                          nominal["motor_speed_rad_s"])
    if has_signals(real, F.LOST_MOTION_SIGNALS) and has_signals(nominal, F.LOST_MOTION_SIGNALS):
        d, w_s, v_s = motion_signals(real, kin)
        dn, wn_s, vn_s = motion_signals(nominal, kin)
        out.lost_motion_m = F.lost_motion_from(d, real["motor_speed_rad_s"])
        out.nominal_lost_motion_m = F.lost_motion_from(dn, nominal["motor_speed_rad_s"])
        out.dead_time_s = (F.stall_time_from(w_s, v_s, real.dt)
                           - F.stall_time_from(wn_s, vn_s, real.dt))
    return out


def has_signals(trace: Trace, names: tuple[str, ...]) -> bool:
    return all(n in trace and np.isfinite(trace[n]).any() for n in names)
