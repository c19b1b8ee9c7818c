"""In-process logs of the independent actuator (no bus): set-points and the rig's load in,
logged columns out, with the bus's timing.

At SYNC k the sensors are sampled (`physics.sense`), the controller computes its demand
from them, and the drive applies the demand of SYNC k-1 during period k (one period of
transport delay, as over CAN). The columns are those a bus log decodes to (SI units):
t_s, setpoint_position_m, setpoint_speed_rad_s, mode, current_demand_a, current_a,
motor_speed_rad_s, motor_angle_rad, position_m, load_force_n.
"""

from __future__ import annotations

import numpy as np

from indie_plant import physics as ph
from indie_plant.controller import Cascade
from indie_plant.params import IndieParams

COLUMNS = ("t_s", "setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
           "current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m", "load_force_n")


def simulate(params: IndieParams, sp_pos: np.ndarray, sp_spd: np.ndarray, mode: np.ndarray,
             load_n: np.ndarray | None = None, controller: Cascade | None = None,
             seed: int = 1) -> dict[str, np.ndarray]:
    """Run the actuator under `controller` (its own cascade by default) over the
    set-points (one per SYNC period); `load_n`: the rig's axial force held over each
    period (N, positive opposes positive travel). Returns the logged columns."""
    n = len(sp_pos)
    if not (len(sp_spd) == len(mode) == n) or (load_n is not None and len(load_n) != n):
        raise ValueError("set-point, mode and load arrays must have one value per period")
    ctrl = controller or Cascade.own(params)
    p = params.vector()
    x = ph.initial_state()
    hist = ph.initial_history(x, p)
    rnd = np.random.default_rng(seed).standard_normal((n, 3))
    meas = np.zeros((n, 5))
    dem = np.zeros(n)
    fext = np.zeros(n) if load_n is None else np.ascontiguousarray(load_n, float)
    ph.run(x, p, hist, ctrl.vector(params), np.ascontiguousarray(sp_pos, float),
         np.ascontiguousarray(sp_spd, float), np.ascontiguousarray(mode, float), fext, rnd,
         meas, dem)
    t = np.arange(n) * params.sync_period_s
    return {"t_s": t, "setpoint_position_m": np.asarray(sp_pos, float),
            "setpoint_speed_rad_s": np.asarray(sp_spd, float),
            "mode": np.asarray(mode, float), "current_demand_a": dem,
            "current_a": meas[:, 0], "motor_speed_rad_s": meas[:, 2],
            "motor_angle_rad": meas[:, 1], "position_m": meas[:, 3],
            "load_force_n": meas[:, 4]}


class Actuator:
    """The actuator one SYNC period at a time (what the CANopen node drives)."""

    def __init__(self, params: IndieParams, seed: int = 1) -> None:
        self.params = params
        self.p = params.vector()
        self.seed = seed
        self.reset()

    def reset(self) -> None:
        self.x = ph.initial_state()
        self.hist = ph.initial_history(self.x, self.p)
        self.k = 0
        self.rng = np.random.default_rng(self.seed)
        self.out = np.zeros(5)

    @property
    def period_s(self) -> float:
        return self.params.sync_period_s

    def sample(self) -> np.ndarray:
        """[current A, angle rad, speed rad/s, LVDT m, load N] at this SYNC."""
        ph.sense(self.x, self.p, self.hist, self.k, self.rng.standard_normal(3), self.out)
        return self.out.copy()

    def step(self, demand_a: float, fext_n: float = 0.0) -> None:
        ph.advance(self.x, self.p, demand_a, fext_n)
        self.k += 1
