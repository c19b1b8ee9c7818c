"""The re-simulation with the LVDT and the encoder delayed apart (the candidates
`lvdt_delay` and `encoder_delay`, `bench.gap.sensors`).

The plant's own `effects.sensor_delay_s` delays both position sensors by the same whole
SYNC periods (`bench.sim.loop`: the controller reads measurement row k - ndelay). A transport
delay of one sensor alone (an LVDT conditioner behind a slow bus, an encoder read through
a second drive) is another loop: the position loop reads an older sample than the speed
loop. Here the controller part reads the LVDT `dl` rows and the encoder `de` rows further
back (both after the model's own delay), the two numbers at the end of its parameter
vector, and the logged columns are shifted the same way: a log records what the
controller read. Gap-side only: the plant and the ECU never delay one sensor alone.
"""

from __future__ import annotations

import numpy as np

from bench.gap.cascade import cascade_rows
from bench.sim.control import controller_step
from bench.sim.loop import (
    R_MODE,
    R_POS,
    R_SPD,
    kernel_advance,
    kernel_measure,
    kernel_truth,
    no_prepare,
    run_loop,
)
from plant_rt import kernel as K
from plant_rt.jit import njit


@njit(inline="always", error_model="numpy")
def _rows(kvec, kd):  # pragma: no cover - compiled
    """The LVDT's and the encoder's measurement rows: kd less the extra delays stored at
    the end of `kvec` (never before the first row)."""
    n = kvec.shape[0]
    kl = kd - int(kvec[n - 2])
    ke = kd - int(kvec[n - 1])
    return (kl if kl > 0 else 0), (ke if ke > 0 else 0)


@njit(inline="always", error_model="numpy")
def ecu_split_control(c, kvec, ref, kk, meas, kd):  # pragma: no cover - compiled
    """The ECU's cascade (`bench.sim.loop.ecu_control`) on an LVDT and an encoder delayed
    apart."""
    kl, ke = _rows(kvec, kd)
    return controller_step(c, kvec, ref[kk, R_POS], ref[kk, R_SPD], ref[kk, R_MODE],
                           meas[kl, K.M_POS], meas[ke, K.M_SPEED])


@njit(inline="always", error_model="numpy")
def cascade_split_control(c, kvec, ref, kk, meas, kd):  # pragma: no cover - compiled
    """The identified cascade (`bench.gap.cascade.cascade_control`) on an LVDT and an
    encoder delayed apart."""
    kl, ke = _rows(kvec, kd)
    return cascade_rows(c, kvec, ref, kk, meas, kl, ke)


@njit(cache=True, nogil=True, error_model="numpy")
def ecu_split_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                       diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """The bench's ECU on the full plant, its LVDT and encoder delayed apart."""
    return run_loop(no_prepare, kernel_measure, kernel_truth, kernel_advance,
                    ecu_split_control, x, p, s, aux, u, noise, ref, kvec, cstate, ndelay,
                    meas_out, dem_out, diag_out, truth_out, applied, k0)


@njit(cache=True, nogil=True, error_model="numpy")
def cascade_split_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out,
                           dem_out, diag_out, truth_out, applied,
                           k0):  # pragma: no cover - compiled
    """An identified cascade on the full plant, its LVDT and encoder delayed apart."""
    return run_loop(no_prepare, kernel_measure, kernel_truth, kernel_advance,
                    cascade_split_control, x, p, s, aux, u, noise, ref, kvec, cstate,
                    ndelay, meas_out, dem_out, diag_out, truth_out, applied, k0)


def with_delays(kvec: np.ndarray, lvdt_periods: int, encoder_periods: int) -> np.ndarray:
    """A controller vector with the extra LVDT and encoder delays (whole periods) at its
    end, as the split controllers read them."""
    return np.concatenate([np.asarray(kvec, float), [float(lvdt_periods),
                                                     float(encoder_periods)]])


def split_columns(meas: np.ndarray, dem: np.ndarray, ndelay: int, lvdt_periods: int,
                  encoder_periods: int) -> dict[str, np.ndarray]:
    """`bench.sim.loop.measured_columns` with the LVDT `lvdt_periods` and the encoder (angle
    and speed) `encoder_periods` further behind the model's own delay `ndelay`."""
    n = len(dem)
    out = {"current_a": meas[:n, K.M_CUR].copy(), "current_demand_a": dem}
    k = np.arange(n)
    il = np.maximum(k - ndelay - lvdt_periods, 0)
    ie = np.maximum(k - ndelay - encoder_periods, 0)
    out["position_m"] = meas[il, K.M_POS]
    out["motor_speed_rad_s"] = meas[ie, K.M_SPEED]
    out["motor_angle_rad"] = meas[ie, K.M_ANGLE]
    return out
