"""Re-simulation of a logged run, whole loop or one path at a time.

Everything here is driven by logged signals only (never by simulation truth):

- `closed_loop`: the bench's own loop (set-point -> ECU -> plant, the compiled
  `bench.loop.ecu_on_plant` that `bench.harness` runs), driven by the logged set-points
  and mode, and by the logged axial load when the log has a load cell. The ECU demand
  computed at SYNC k is applied by the drive during period k+1, exactly as over the bus.
- `open_loop`: the logged ECU demand replayed into the plant with the same one-period
  hold (the same loop with the demand from a table; isolates current demand -> current:
  the drive path).
- `mechanics_replay`: the logged demand replayed in short segments, the mechanical state
  re-synchronised at each segment start from the measured motor speed (isolates
  current -> motor speed: the mechanics path, without the drift of a long open-loop run).
- `screw_kinematics` / `encoder_consistency`: the nominal kinematics and sensor dynamics
  applied to the measured encoder angle (motor angle -> nut position: the screw path;
  encoder speed vs angle and LVDT: the sensors).

Units are SI throughout: positions m (nut), motor angles rad, motor speeds rad/s,
currents A, time s. Sign conventions are the plant's (`plant_rt.kernel`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench.control import NC as CTRL_NC
from bench.control import ControllerParams
from bench.loop import (
    NT,
    delay_periods,
    ecu_on_plant,
    ecu_reference,
    kernel_advance,
    kernel_measure,
    kernel_truth,
    measured_columns,
    no_columns,
    run_chunks,
    run_loop,
    table_control,
)
from plant_rt import kernel as K
from plant_rt.jit import njit
from plant_rt.model import Plant
from plant_rt.params import PlantParams

FAST = {"drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic"}
"""Fast plant mode used for fitting: averaged PWM, massless balls (~240x real time)."""

SIGNALS = ("current_a", "motor_speed_rad_s", "position_m", "encoder_position_m")
"""Measured signals compared in the closed loop. ``encoder_position_m`` is the encoder
angle relative to its first sample converted to nut travel with the nominal ratio and
lead (tau p / 2 pi, m/rad) plus the first LVDT sample: the motor angle in position units."""


@dataclass
class Drive:
    """What drives a re-simulation: logged set-points, mode and demand (SYNC rate)."""
    t: np.ndarray
    sp_pos: np.ndarray
    sp_spd: np.ndarray
    mode: np.ndarray
    demand: np.ndarray          # logged ECU current demand (A), NaN if not logged
    x0_m: float                 # LVDT reading at the start (m)
    x0_true_m: float | None = None   # nut position at the start from an absolute encoder
    load_n: np.ndarray | None = None  # load cell (N) at each SYNC, None: no load logged

    def applied_load(self, n: int) -> np.ndarray:
        """External force (N) held over each of the first `n` periods: the load cell's
        reading at SYNC k + 1 is the force averaged over period k (zeros without one)."""
        if self.load_n is None or n == 0:
            return np.zeros(n)
        f = np.nan_to_num(np.asarray(self.load_n[:n], float))
        return np.append(f[1:], f[-1])


def angle_to_travel(params: PlantParams) -> float:
    """Nut travel per motor radian (m/rad): tau p / 2 pi with `params`' ratio and lead."""
    return params.reducer.ratio * params.screw.lead_m / (2.0 * math.pi)


def initial_plant(params: PlantParams, x0_true_m: float) -> Plant:
    """A plant at rest with the nut at `x0_true_m` (preload seated, stiction held)."""
    plant = Plant(params)
    if x0_true_m:
        dth = x0_true_m * 2.0 * math.pi / params.screw.lead_m
        plant.x[K.TH] += dth
        plant.x[K.X1] += x0_true_m
        plant.x[K.X2] += x0_true_m
        plant.x[K.ZB1] += x0_true_m * plant.param_vector[K.P_G]
        plant.x[K.ZB2] += x0_true_m * plant.param_vector[K.P_G]
        plant.x[K.LY] = x0_true_m
    return plant


def _plant_inputs(params: PlantParams, drive: Drive, n: int) -> np.ndarray:
    """The kernel inputs of the first `n` periods: `params`' effects held (no schedule, no
    noise) and the logged load replayed."""
    u0 = np.zeros(K.NU)
    e = params.effects
    u0[K.U_PRELOAD], u0[K.U_BACKLASH], u0[K.U_FSCALE] = e.preload_n, e.backlash_m, e.friction_scale
    u0[K.U_VSCALE] = e.viscous_scale
    u0[K.U_IGAIN] = params.sensors.current_gain
    u0[K.U_IOFF] = params.sensors.current_offset_a
    u = np.empty((n, K.NU))
    u[:] = u0
    u[:, K.U_FEXT] = drive.applied_load(n)
    return u


def _x0_true(params: PlantParams, drive: Drive) -> float:
    """Nut position at the start: from the absolute encoder angle when the log has one,
    else the position whose LVDT reading (gain, offset) is the logged initial reading."""
    if drive.x0_true_m is not None:
        return drive.x0_true_m
    se = params.sensors
    return (drive.x0_m - se.lvdt_offset_m) / se.lvdt_gain


def _run(entry: Callable[..., int], params: PlantParams, drive: Drive, n: int, aux: np.ndarray,
         noise: np.ndarray, ref: np.ndarray, kvec: np.ndarray, cstate: np.ndarray,
         ndelay: int) -> tuple[np.ndarray, np.ndarray]:
    """Run `entry` (a `bench.loop` entry point) on the plant at rest at the log's start;
    after a non-finite state the remaining periods are NaN. Returns (meas, demand)."""
    plant = initial_plant(params, _x0_true(params, drive))
    meas = np.zeros((n, K.NM))
    dem = np.zeros(n)
    got = run_chunks(entry, plant.x.copy(), plant.param_vector, plant.sensor_vector, aux,
                     _plant_inputs(params, drive, n), noise, ref, kvec, cstate, ndelay, meas,
                     dem, np.zeros((n, K.NO)), np.zeros((n, NT)))
    meas[got:] = np.nan
    dem[got:] = np.nan
    return meas, dem


def closed_loop(params: PlantParams, drive: Drive, n: int | None = None,
                cparams: ControllerParams | None = None,
                noise: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Re-simulate the closed loop over the first `n` periods of `drive`.

    Returns the measured columns (current_a, motor_speed_rad_s, motor_angle_rad,
    position_m, current_demand_a) as the bus would log them, sensor delay included.
    `noise` (n, 3): optional white noise (A, m, rad/s) per SYNC, as the plant draws it.
    """
    n = len(drive.t) if n is None else min(n, len(drive.t))
    cparams = cparams or ControllerParams(sample_period_s=params.sim.sync_period_s)
    nz = np.zeros((n, 3)) if noise is None else np.ascontiguousarray(noise[:n])
    nd = delay_periods(params)
    meas, dem = _run(ecu_on_plant, params, drive, n, no_columns(n), nz,
                     ecu_reference(drive.sp_pos[:n], drive.sp_spd[:n], drive.mode[:n]),
                     cparams.vector(), np.zeros(CTRL_NC), nd)
    return _columns(meas, dem, nd)


def _columns(meas: np.ndarray, dem: np.ndarray, ndelay: int) -> dict[str, np.ndarray]:
    out = measured_columns(meas, dem, ndelay)
    out["current_a"] = out["current_a"].copy()
    return out


# --- demand replayed from the log ------------------------------------------------------
# aux rows of the replay: re-synchronise now (1/0), the motor speed to set (rad/s)
A_SYNC, A_W = 0, 1


@njit(inline="always", error_model="numpy")
def resync(x, p, aux, kk):  # pragma: no cover - compiled
    """Set the screw speed (and encoder filter) to the motor speed aux[kk, A_W] where
    aux[kk, A_SYNC] says so: moving (> 0.5 rad/s) frees the stiction states, else the
    screw is held."""
    if aux[kk, A_SYNC] > 0.0:
        tau = p[K.P_TAU]
        kin = p[K.P_LEAD] / (2.0 * math.pi)
        om = aux[kk, A_W] * tau
        x[K.OM] = om
        x[K.V1] = kin * om
        x[K.V2] = kin * om
        if abs(aux[kk, A_W]) > 0.5:
            x[K.STS] = 0.0
            x[K.STN1] = 0.0
            x[K.STN2] = 0.0
        else:
            x[K.OM] = 0.0
            x[K.V1] = 0.0
            x[K.V2] = 0.0
            x[K.STS] = 1.0
            x[K.STN1] = 1.0
            x[K.STN2] = 1.0
        x[K.EY] = x[K.OM] / tau
        x[K.EYD] = 0.0


@njit(cache=True, error_model="numpy")
def table_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                   diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """The logged demand (`bench.loop.table_control`) on the full plant, re-synchronised
    where aux says so."""
    return run_loop(resync, kernel_measure, kernel_truth, kernel_advance, table_control,
                    x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                    diag_out, truth_out, applied, k0)


def _replay(params: PlantParams, drive: Drive, n: int, aux: np.ndarray
            ) -> dict[str, np.ndarray]:
    """The logged demand of SYNC k held over period k + 1 (NaN: 0), sensors without noise."""
    table = np.nan_to_num(np.asarray(drive.demand[:n], float)).reshape(n, 1)
    meas, _ = _run(table_on_plant, params, drive, n, aux, np.zeros((n, 3)), table,
                   np.zeros(0), np.zeros(0), 0)
    applied = np.zeros(n)
    applied[1:] = np.nan_to_num(drive.demand[:n - 1])
    return _columns(meas, applied, delay_periods(params))


def open_loop(params: PlantParams, drive: Drive, n: int | None = None) -> dict[str, np.ndarray]:
    """Replay the logged ECU demand (held one period, as the bus does) into the plant."""
    n = len(drive.t) if n is None else min(n, len(drive.t))
    return _replay(params, drive, n, np.zeros((n, 2)))


def mechanics_replay(params: PlantParams, drive: Drive, speed_meas: np.ndarray,
                     segment: int = 50, n: int | None = None) -> dict[str, np.ndarray]:
    """Replay the logged demand in segments of `segment` periods, re-synchronising the
    screw speed (and encoder filter) to the measured motor speed at each segment start.

    The residual of motor speed against this replay is the mechanics path's gap
    (current -> motor speed) with a bounded drift. `speed_meas` should be lightly
    smoothed (noise enters at each re-synchronisation).
    """
    n = len(drive.t) if n is None else min(n, len(drive.t))
    # the measured speed is sensor_delay old: re-synchronise on the sample that describes now
    nd = delay_periods(params)
    sync = np.empty(n)
    sync[:n - nd] = speed_meas[nd:n] if nd else speed_meas[:n]
    if nd:
        sync[n - nd:] = speed_meas[n - 1]
    aux = np.zeros((n, 2))
    if segment > 0:
        aux[::segment, A_SYNC] = 1.0
    aux[:, A_W] = sync / params.sensors.encoder_gain
    return _replay(params, drive, n, aux)


# --- kinematic paths -----------------------------------------------------------------

def second_order(y: np.ndarray, dt: float, natural_rad_s: float, damping: float) -> np.ndarray:
    """`y` (sampled every `dt`, linear between samples) through the unit-gain second-order
    sensor filter sigma^2 / (s^2 + 2 zeta sigma s + sigma^2) of eq. 5.1, exactly."""
    from scipy.signal import lsim
    n = len(y)
    if n < 2:
        return y.copy()
    t = np.arange(n) * dt
    w = natural_rad_s
    # settled on the first sample at t = 0 (the plant's sensors start at rest)
    _, out, _ = lsim(([w * w], [1.0, 2.0 * damping * w, w * w]), y - y[0], t)
    return np.asarray(out) + y[0]


def first_order(y: np.ndarray, dt: float, tau_s: float) -> np.ndarray:
    """`y` through a unit-gain first-order lag of time constant `tau_s` (exact ZOH form,
    starting settled on the first sample)."""
    if tau_s <= 0.0 or len(y) == 0:
        return y.copy()
    a = math.exp(-dt / tau_s)
    from scipy.signal import lfilter
    out, _ = lfilter([1.0 - a], [1.0, -a], y, zi=[a * y[0]])
    return out


def encoder_travel(angle_rad: np.ndarray, x0_m: float, params: PlantParams) -> np.ndarray:
    """Motor angle (rad) as nut travel (m): (theta - theta_0) tau p / 2 pi + x_0."""
    return (angle_rad - angle_rad[0]) * angle_to_travel(params) + x0_m


def screw_kinematics(angle_rad: np.ndarray, x0_m: float, params: PlantParams,
                     dt: float) -> np.ndarray:
    """The LVDT reading the nominal screw predicts from the measured motor angle: rigid,
    backlash-free kinematics (lead, ratio) through the nominal LVDT dynamics (eq. 5.1)."""
    se = params.sensors
    x = encoder_travel(angle_rad, x0_m, params)
    return second_order(x, dt, se.lvdt_natural_rad_s, se.lvdt_damping)


def encoder_speed_from_angle(angle_rad: np.ndarray, params: PlantParams,
                             dt: float) -> np.ndarray:
    """The encoder speed (rad/s) the nominal sensor predicts from the measured angle:
    the angle's derivative through the encoder dynamics (eq. 5.1)."""
    se = params.sensors
    w = np.gradient(angle_rad, dt) if len(angle_rad) > 1 else np.zeros_like(angle_rad)
    # the central difference is centred half a sample late relative to the filter input
    return second_order(w, dt, se.encoder_natural_rad_s, se.encoder_damping)
