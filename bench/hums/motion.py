"""Streaming (causal, stateful) signals behind lost motion and reversal dead time.

Lost motion (m) is the hysteresis between the encoder travel (motor angle x tau p / 2 pi
through the nominal LVDT dynamics) and the LVDT reading, split by the direction of
motion: median while moving forward minus median while moving back. A rigid screw gives
0; backlash b gives about b / (cos alpha sin beta) once preload no longer takes it up.
Reversal dead time (s): per command period, the time the motor moves (|encoder speed| >
10 % of its peak) while the nut does not (|LVDT speed| < 5 % of its peak), real minus
nominal. The formulas are `bench.hums.formulas.lost_motion_from` / `stall_time_from`;
this module makes their input signals, in pieces or whole, with the same result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from bench.core.paramset import ParamSet
from bench.hums.formulas import LOST_MOTION_SIGNALS, lost_motion_from, stall_time_from
from bench.signals.trace import Trace
from plant_rt.params import P


@dataclass(frozen=True)
class Kinematics(ParamSet):
    """Nominal screw kinematics and LVDT dynamics used by lost motion (from PlantParams),
    with units, ranges and sources as the plant's (`bench.core.paramset`)."""
    _group: ClassVar[str] = "kinematics"
    travel_per_motor_rad_m: float = P(0.25 * 5e-3 / (2 * math.pi), "m/rad", 1e-9, 1.0,
                                      "nut travel per motor radian, tau p / 2 pi",
                                      "tables 5.4 (p) and 5.3 (tau), eq. 5.33")
    lvdt_natural_rad_s: float = P(1256.0, "rad/s", 1.0, 1e6,
                                  "LVDT eigenfrequency sigma_pos", "table 5.1")
    lvdt_damping: float = P(0.8, "-", 0.05, 5.0, "LVDT damping zeta_pos", "table 5.1")

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
