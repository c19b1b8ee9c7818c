"""The independent actuator's own controller: a PI position + PI speed cascade.

Its structure differs from the bench's ECU (position P on the LVDT + speed PI at every
SYNC): the position loop is PI and reads the motor encoder as nut travel, and the cascade
runs every second SYNC period (2 ms sample time, its demand held over both periods).
`Cascade.like_bench_ecu` gives the other structure (position P on the LVDT at every
SYNC) with gains given as numbers, which is how a rig behind the bus sees the bench's
ECU; this package never imports the bench.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from indie_plant.params import IndieParams
from indie_plant.physics import (
    C_EVERY,
    C_ILIM,
    C_KIP,
    C_KIS,
    C_KPP,
    C_KPS,
    C_SRC,
    C_T,
    C_TRAVEL,
    C_WLIM,
    NCV,
    SOURCE_ENCODER,
    SOURCE_LVDT,
)


@dataclass(frozen=True)
class Cascade:
    """Gains and structure (SI): position PI (rad/s per m, rad/s per m s) on the LVDT or
    the encoder, speed PI (A s/rad, A/rad), limits, sample time in SYNC periods."""
    position_source: float
    kp_pos: float
    ki_pos: float
    kp_spd: float
    ki_spd: float
    speed_limit_rad_s: float
    current_limit_a: float
    every_periods: int

    @classmethod
    def own(cls, p: IndieParams) -> Cascade:
        """The actuator's own cascade: 8 Hz position bandwidth with its integral zero at
        1 Hz on the encoder travel; speed PI at 25 Hz crossover on the rotor inertia
        (kp = 2 pi 25 J / kt) with its zero at 3 Hz; 2 ms sample time; 300 rad/s and
        the drive's current limit."""
        kpp = 2.0 * math.pi * 8.0 / p.travel_per_rad
        kps = 2.0 * math.pi * 25.0 * p.inertia_kg_m2 / p.kt_nm_per_a
        return cls(SOURCE_ENCODER, kpp, kpp * 2.0 * math.pi * 1.0, kps,
                   kps * 2.0 * math.pi * 3.0, 300.0, p.current_limit_a, 2)

    @classmethod
    def like_bench_ecu(cls, kp_pos: float, kp_spd: float, ki_spd: float,
                       speed_limit: float, current_limit: float) -> Cascade:
        """Position P on the LVDT + speed PI at every SYNC, gains given as numbers."""
        return cls(SOURCE_LVDT, kp_pos, 0.0, kp_spd, ki_spd, speed_limit, current_limit, 1)

    def vector(self, p: IndieParams) -> np.ndarray:
        """The compiled law's vector (`indie_plant.physics.cascade_step`)."""
        v = np.zeros(NCV)
        v[C_SRC], v[C_KPP], v[C_KIP] = self.position_source, self.kp_pos, self.ki_pos
        v[C_KPS], v[C_KIS] = self.kp_spd, self.ki_spd
        v[C_WLIM], v[C_ILIM] = self.speed_limit_rad_s, self.current_limit_a
        v[C_EVERY], v[C_T], v[C_TRAVEL] = self.every_periods, p.sync_period_s, p.travel_per_rad
        return v
