"""The closed loop at the SYNC rate, written once: a plant and a pluggable controller.

The coupling is the bus's: at SYNC k the plant's sensors are sampled (TPDOs), the
controller computes a demand from the samples (the LVDT and encoder ones `ndelay` periods
old, `effects.sensor_delay_s`), and that demand is applied by the drive during period k+1
(RPDO applied at the next SYNC): one period of delay plus sample-and-hold. The loop stops
after the first period that leaves the plant's state non-finite.

`run_loop` takes its parts as compiled functions and is inlined into a small entry point
per combination, where the parts are direct calls: one compiled loop each, no Python per
step, cached on disk. (numba 0.6x does not reuse the disk cache of a function whose
arguments are functions, and a cached caller that passes functions to one it does not
inline embeds run-time pointers and is not cached either.) The parts:

- plant:  prepare(x, p, aux, kk) before the sensors are sampled (a state
  re-synchronisation; `no_prepare` otherwise), measure(x, p, s, noise, kk, m) into the
  `plant_rt.kernel` M_* layout, truth(x, p, truth_out, k) simulation-only signals,
  advance(x, p, u, kk, applied, noise, diag_out, k) -> bool one SYNC period holding
  `applied`, False when the state went non-finite. Here: the full plant
  (`plant_rt.kernel`); the monitoring model's are in `bench.hums.monitor`.
- controller: control(c, kvec, ref, kk, meas_out, kd) -> demand, with its state `c`, its
  parameters `kvec`, this period's row kk of the reference table `ref` and the (delayed)
  measurement row kd. Here: the ECU's position/speed cascade (`bench.sim.control.
  controller_step`, any gains, limits and sample time in `kvec`) and `table_control`, a
  demand replayed from a table (a logged ECU demand, or a measured current for a rig
  without the bench's ECU).
Parts take whole tables and row indices (`kk` into the chunk's inputs, `k` = k0 + kk into
the whole run's outputs) and are inlined into the entry point (inline="always").

Every entry point has the signature of `ecu_on_plant` (the monitor's is
`bench.hums.monitor.ecu_on_monitor`, the log replay's `bench.gap.resim.table_on_plant`);
`run_chunks` runs one over a whole run in chunks, carrying the state across them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bench.sim.control import controller_step
from plant_rt import kernel as K
from plant_rt.jit import njit
from plant_rt.params import PlantParams

# the full plant's simulation-only signals sampled at each SYNC (`kernel_truth`)
TRUTH_FROM_STATE = ("true_position_m", "true_current_a", "true_motor_speed_rad_s",
                    "motor_torque_nm", "temperature_k")
NT = len(TRUTH_FROM_STATE)


def delay_periods(params: PlantParams) -> int:
    """The sensor delay in whole SYNC periods (LVDT and encoder samples)."""
    return int(round(params.effects.sensor_delay_s / params.sim.sync_period_s))


@njit(inline="always", error_model="numpy")
def run_loop(prepare, measure, truth, advance, control, x, p, s, aux, u, noise, ref, kvec,
             cstate, ndelay, meas_out, dem_out, diag_out, truth_out, applied,
             k0):  # pragma: no cover - compiled
    """Run len(ref) periods from SYNC k0; returns how many ran (fewer: the state went
    non-finite). Per-period inputs (aux, u, noise, ref) start at the chunk; the outputs
    (meas_out, dem_out, diag_out, truth_out) are whole-run arrays indexed k0 + kk, so the
    sensor delay reads history across chunk boundaries. `applied`: the demand held over the
    first period (the last one of the previous chunk, 0 at the start)."""
    n = ref.shape[0]
    m = np.zeros(K.NM)
    for kk in range(n):
        k = k0 + kk
        prepare(x, p, aux, kk)
        measure(x, p, s, noise, kk, m)
        for j in range(K.NM):
            meas_out[k, j] = m[j]
        kd = k - ndelay if k >= ndelay else 0
        d = control(cstate, kvec, ref, kk, meas_out, kd)
        dem_out[k] = d
        truth(x, p, truth_out, k)
        ok = advance(x, p, u, kk, applied, noise, diag_out, k)
        applied = d
        if not ok:
            return kk + 1
    return n


# --- plant parts: the full plant of chapter 5 ---------------------------------------------

@njit(inline="always", error_model="numpy")
def no_prepare(x, p, aux, kk):  # pragma: no cover - compiled
    """No state change before the sensors are sampled."""


@njit(inline="always", error_model="numpy")
def kernel_measure(x, p, s, noise, kk, m):  # pragma: no cover - compiled
    """The plant's sensors (eq. 5.1-5.2), noise[kk] = (A, m, rad/s) for this SYNC."""
    K.measure(x, s, noise[kk], m)


@njit(inline="always", error_model="numpy")
def kernel_truth(x, p, out, k):  # pragma: no cover - compiled
    """TRUTH_FROM_STATE at this SYNC into out[k]."""
    out[k, 0] = 0.5 * (x[K.X1] + x[K.X2])
    out[k, 1] = x[K.I]
    out[k, 2] = x[K.OM] / p[K.P_TAU]
    out[k, 3] = x[K.TQ]
    out[k, 4] = x[K.TEMP]


@njit(inline="always", error_model="numpy")
def kernel_advance(x, p, u, kk, applied, noise, diag, k):  # pragma: no cover - compiled
    """One SYNC period of the plant, diagnostics into diag[k]: the drive holds `applied`;
    the current sensor's noise sample of this SYNC stays in the drive's feedback over the
    period. The period's kernel inputs u[kk] receive both."""
    uk = u[kk]
    uk[K.U_IDEM] = applied
    uk[K.U_INOISE] = noise[kk, 0]
    K.advance(x, p, uk, diag[k])
    return np.isfinite(x[K.OM])


# --- controller parts -----------------------------------------------------------------------
# ECU reference rows: (position set-point m, speed set-point rad/s, mode)
R_POS, R_SPD, R_MODE = 0, 1, 2
NR_ECU = 3


@njit(inline="always", error_model="numpy")
def ecu_control(c, kvec, ref, kk, meas, kd):  # pragma: no cover - compiled
    """The ECU's cascade (section 5.2) on the LVDT position and encoder speed."""
    return controller_step(c, kvec, ref[kk, R_POS], ref[kk, R_SPD], ref[kk, R_MODE],
                           meas[kd, K.M_POS], meas[kd, K.M_SPEED])


@njit(inline="always", error_model="numpy")
def table_control(c, kvec, ref, kk, meas, kd):  # pragma: no cover - compiled
    """The demand of this SYNC from a table (ref[kk, 0]), applied over the next period."""
    return ref[kk, 0]


# --- entry points -------------------------------------------------------------------------

@njit(cache=True, nogil=True, error_model="numpy")
def ecu_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                 diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """The bench's loop: the ECU on the full plant (harness, gap re-simulation). It
    releases the GIL (``nogil``), as the gap's other loops do: the threads of the process
    that runs it (a Dask scheduler starting beside the diagnosis) go on meanwhile."""
    return run_loop(no_prepare, kernel_measure, kernel_truth, kernel_advance, ecu_control,
                    x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                    diag_out, truth_out, applied, k0)


def ecu_reference(sp_pos: np.ndarray, sp_spd: np.ndarray, mode: np.ndarray) -> np.ndarray:
    """The ECU's reference table (n, NR_ECU) from set-points and mode."""
    return np.column_stack([np.asarray(sp_pos, float), np.asarray(sp_spd, float),
                            np.asarray(mode, float)])


def no_columns(n: int) -> np.ndarray:
    """An (n, 0) table: per-period inputs or outputs a part does not use."""
    return np.zeros((n, 0))


def run_chunks(entry: Callable[..., int], x: np.ndarray, p: np.ndarray, s: np.ndarray,
               aux: np.ndarray, u: np.ndarray, noise: np.ndarray, ref: np.ndarray,
               kvec: np.ndarray, cstate: np.ndarray, ndelay: int, meas: np.ndarray,
               dem: np.ndarray, diag: np.ndarray, truth: np.ndarray,
               chunk: int | None = None, on_chunk: Callable[[int], None] | None = None,
               applied: float = 0.0, start: int = 0, stop: int | None = None) -> int:
    """Run `entry` over periods `start` to `stop` (all len(ref) periods by default),
    `chunk` periods per compiled call (all at once without), calling `on_chunk(periods)`
    after each; returns the periods done (counted from 0: `start` and those run).
    `applied`: the demand held over the first period (a previous run's last demand).

    The state (x, controller state, applied demand) carries across chunk boundaries and
    the outputs are whole-run arrays, so chunking, or running on from a kept state at
    `start`, does not change the result."""
    n = ref.shape[0] if stop is None else stop
    step = max(1, n - start) if chunk is None else max(1, chunk)
    done = start
    while done < n:
        k1 = min(n, done + step)
        got = entry(x, p, s, aux[done:k1], u[done:k1], noise[done:k1], ref[done:k1], kvec,
                    cstate, ndelay, meas, dem, diag, truth, applied, done)
        applied = dem[k1 - 1]
        if on_chunk is not None:
            on_chunk(k1 - done)
        if got < k1 - done:
            return done + got
        done = k1
    return n


def measured_columns(meas: np.ndarray, dem: np.ndarray, ndelay: int) -> dict[str, np.ndarray]:
    """The measured columns as the bus logs them: the current of SYNC k, the encoder and
    LVDT samples `ndelay` periods old (the first one repeated), the demand of SYNC k."""
    n = len(dem)
    out = {"current_a": meas[:n, K.M_CUR], "current_demand_a": dem}
    idx = np.maximum(np.arange(n) - ndelay, 0)
    for c, j in (("motor_speed_rad_s", K.M_SPEED), ("motor_angle_rad", K.M_ANGLE),
                 ("position_m", K.M_POS)):
        out[c] = meas[idx, j]
    return out
