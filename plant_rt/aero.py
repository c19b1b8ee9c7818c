"""The aerodynamic load's gusts (`load.kind = aero`), as plain Python and numpy.

The aero load on the nut is F_ext = K_aero x_n + F_gust (`plant_rt.kernel._ext_force`): a
hinge moment that grows with the surface's deflection, restoring (positive F_ext opposes
positive motion, eq. 5.30), plus gusts. The gust force is first-order coloured noise,
a Dryden-type filter of white noise with correlation time tau, stationary from the start
and held over each SYNC period:

    g[0] = sigma w[0],  g[k+1] = a g[k] + sigma sqrt(1 - a^2) w[k+1],  a = exp(-T/tau)

with w from its own seeded stream (`load.gust_seed`). The live node draws it period by
period (`GustGenerator.next`), the in-process harness the same numbers at once
(`gust_sequence`), so a lockstep bus run and an in-process run see the same gusts.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from plant_rt.params import PlantParams

GUST_STREAM = 21     # the seed stream of the gusts (apart from the sensors' and wear's)
_BLOCK = 4096        # normals drawn per block: the same numbers however they are consumed


class GustGenerator:
    """The gust force per SYNC period, one value per `next()` (N); zero unless aero."""

    def __init__(self, params: PlantParams) -> None:
        ld = params.load
        self.on = ld.kind == "aero" and ld.gust_std_n > 0.0
        self.sigma = ld.gust_std_n
        self.a = math.exp(-params.sim.sync_period_s / ld.gust_time_constant_s)
        self.b = ld.gust_std_n * math.sqrt(1.0 - self.a * self.a)
        self._rng = np.random.default_rng([int(ld.gust_seed), GUST_STREAM])
        self._w = np.zeros(0)
        self._i = 0
        self._g: float | None = None

    def _normal(self) -> float:
        if self._i >= len(self._w):
            self._w = self._rng.standard_normal(_BLOCK)
            self._i = 0
        v = float(self._w[self._i])
        self._i += 1
        return v

    def next(self) -> float:
        """The gust force of the next period (N)."""
        if not self.on:
            return 0.0
        if self._g is None:
            self._g = self.sigma * self._normal()
        else:
            self._g = self.a * self._g + self.b * self._normal()
        return self._g


def gust_sequence(params: PlantParams, n: int) -> np.ndarray:
    """The first `n` gust forces of `GustGenerator(params)` (N per period)."""
    gen = GustGenerator(params)
    return np.array([gen.next() for _ in range(n)], dtype=float)
