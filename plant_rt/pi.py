"""The PI law with clamping anti-windup, the one copy of it (thesis section 5.2).

Three loops use it with their own gains and limits: the drive's current PI in the plant
(`plant_rt.kernel.advance`: error in A, output the set voltage in V, limit the DC bus
V_a), the same current PI in the monitoring model (`bench.hums.monitor`), and the ECU's
speed PI (`bench.sim.control.controller_step`: error in rad/s, output the current demand in
A, limit i_max).
"""

from __future__ import annotations

from plant_rt.jit import njit


@njit(cache=True, inline="always", error_model="numpy")
def clamped_pi(e: float, integ: float, kp: float, ki: float, dt: float,
               limit: float) -> tuple[float, float]:
    """One sample of u = kp e + integral, saturated at +-`limit`; returns (u, new integral).

    Clamping anti-windup: the integral (integ += ki e dt, forward Euler) stops while the
    output is saturated and the error pushes it further out. Inlined into each caller, so
    it compiles with the caller's own flags (the kernel's rounding-safe fast-math flags).
    """
    u_un = kp * e + integ
    u = u_un
    if u > limit:
        u = limit
    elif u < -limit:
        u = -limit
    if not (u != u_un and e * u_un > 0.0):
        integ += ki * e * dt
    return u, integ
