"""The ECU controller: position P and speed PI at the SYNC rate (thesis section 5.2).

The current loop lives in the drive (plant_rt), so the ECU sends a current demand; see
docs/model.md, "Control partition and the bus delay". The same compiled `controller_step` runs in the live ECU
(bench.ecu, one call per SYNC) and in the one compiled closed loop (`bench.sim.loop`, used by
the harness, the gap re-simulation and the monitoring model), so all give the same demand
for the same measurements. Its speed PI is the drive's clamped PI law (`plant_rt.pi`).

Gains are designed here, since the thesis does not print them:
- position P: 6 Hz position bandwidth, K = 2 pi 6 / (tau p / 2 pi) (rad/s)/m, i.e. the
  thesis' requirement of section 5.2.2 (in thesis units, K / 285.7 V/m);
- speed PI: 30 Hz crossover on the motor-side inertia (Kp = 2 pi 30 J / k_t) with the
  integral zero at 1/8 of it: the thesis' 60 Hz / 67 deg / 14 dB is not reachable
  through a 1 kHz bus with one period of delay (docs/model.md gives the loop shapes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from bench.core.paramset import ParamSet
from bench.signals.trace import MODE_IDLE, MODE_POSITION, MODE_SPEED
from plant_rt.jit import njit
from plant_rt.params import THESIS, P
from plant_rt.pi import clamped_pi

# controller state vector: [speed PI integrator (A), last demand (A)]
C_INT, C_LAST = 0, 1
NC = 2
# controller parameter vector
(K_POS_KP, K_SPD_KP, K_SPD_KI, K_SPD_LIM, K_CUR_LIM, K_TS) = range(6)
NK = 6

THESIS_SET_GAIN_V_PER_M = 285.7   # K_SET of table 5.1: thesis position units are volts


def position_gain_for_bandwidth(bandwidth_hz: float, ratio: float = THESIS.reducer.ratio,
                                lead_m: float = THESIS.screw.lead_m) -> float:
    """Position P gain (motor rad/s per m) giving `bandwidth_hz` with a rigid screw:
    K = 2 pi f_bw / (tau p / 2 pi) (the nut speed per motor speed, eq. 5.33)."""
    return 2 * math.pi * bandwidth_hz / (ratio * lead_m / (2 * math.pi))


@dataclass(frozen=True)
class ControllerParams(ParamSet):
    """ECU gains and limits (SI; thesis units are volts for position), with units, ranges
    and sources as the plant's (`bench.core.paramset`)."""
    _group: ClassVar[str] = "controller"
    position_kp_rad_s_per_m: float = P(position_gain_for_bandwidth(6.0), "(rad/s)/m", 0.0, 1e7,
                                       "position P gain: 6 Hz position bandwidth",
                                       "chosen (section 5.2.2 requirement; thesis gain "
                                       "not given)")
    speed_kp_a_s_per_rad: float = P(0.5, "A s/rad", 0.0, 1e3,
                                    "speed PI proportional gain: 30 Hz crossover, "
                                    "2 pi 30 J / k_t", "chosen (docs/model.md)")
    speed_ki_a_per_rad: float = P(12.0, "A/rad", 0.0, 1e6,
                                  "speed PI integral gain: zero at 1/8 of the crossover",
                                  "chosen (docs/model.md)")
    speed_limit_rad_s: float = P(251.0, "rad/s", 0.0, 1e4, "motor speed saturation",
                                 "section 5.7.1")
    current_limit_a: float = P(25.0, "A", 0.0, 1000.0, "current demand limit i_max",
                               "table 5.2")
    sample_period_s: float = P(1e-3, "s", 1e-4, 0.1, "ECU sample (SYNC) period",
                               "chosen (as sim.sync_period_s, docs/model.md)")

    @property
    def position_kp_thesis_units(self) -> float:
        """The position gain in the thesis' units ((rad/s)/V, with K_SET = 285.7 V/m)."""
        return self.position_kp_rad_s_per_m / THESIS_SET_GAIN_V_PER_M

    def vector(self) -> np.ndarray:
        k = np.zeros(NK)
        k[K_POS_KP] = self.position_kp_rad_s_per_m
        k[K_SPD_KP] = self.speed_kp_a_s_per_rad
        k[K_SPD_KI] = self.speed_ki_a_per_rad
        k[K_SPD_LIM] = self.speed_limit_rad_s
        k[K_CUR_LIM] = self.current_limit_a
        k[K_TS] = self.sample_period_s
        return k


@njit(cache=True, error_model="numpy")
def controller_step(c: np.ndarray, k: np.ndarray, sp_pos: float, sp_speed: float, mode: float,
                    pos: float, speed: float) -> float:
    """One ECU sample: the current demand (A) from set-points and measurements.

    mode 1 (position): speed demand = P(position error) saturated at the speed limit;
    mode 2 (speed, the thesis' open-loop tests): speed demand = sp_speed;
    mode 0 (idle): demand 0, integrator reset.
    Speed PI with clamping anti-windup, output saturated at the current limit (sec. 5.2).
    """
    if mode == 0.0 or not (math.isfinite(pos) and math.isfinite(speed)):
        c[C_INT] = 0.0
        c[C_LAST] = 0.0
        return 0.0
    if mode == 1.0:
        w_dem = k[K_POS_KP] * (sp_pos - pos)
    else:
        w_dem = sp_speed
    lim = k[K_SPD_LIM]
    if w_dem > lim:
        w_dem = lim
    elif w_dem < -lim:
        w_dem = -lim
    # speed PI, output the current demand saturated at i_max (the drive's law, plant_rt.pi)
    i_dem, c[C_INT] = clamped_pi(w_dem - speed, c[C_INT], k[K_SPD_KP], k[K_SPD_KI], k[K_TS],
                                 k[K_CUR_LIM])
    c[C_LAST] = i_dem
    return i_dem


class Controller:
    """The ECU controller as an object (what the live ECU holds)."""

    def __init__(self, params: ControllerParams | None = None) -> None:
        self.params = params or ControllerParams()
        self._k = self.params.vector()
        self._c = np.zeros(NC)

    def reset(self) -> None:
        self._c[:] = 0.0

    def step(self, setpoint_position_m: float, setpoint_speed_rad_s: float, mode: int,
             position_m: float, motor_speed_rad_s: float) -> float:
        return float(controller_step(self._c, self._k, setpoint_position_m,
                                     setpoint_speed_rad_s, float(mode), position_m,
                                     motor_speed_rad_s))


__all__ = ["ControllerParams", "Controller", "controller_step", "MODE_IDLE", "MODE_POSITION",
           "MODE_SPEED", "position_gain_for_bandwidth"]
