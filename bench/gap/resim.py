"""Re-simulation of a logged run, whole loop or one path at a time.

Everything here is driven by logged signals only (never by simulation truth):

- `closed_loop`: the same loop as the bench (set-point -> ECU -> plant), driven by the
  logged set-points and mode, and by the logged axial load when the log has a load cell. The ECU demand computed at SYNC k is applied by the drive
  during period k+1, exactly as over the bus and in `bench.harness`.
- `open_loop`: the logged ECU demand replayed into the plant with the same one-period
  hold (isolates current demand -> current: the drive path).
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
from dataclasses import dataclass

import numpy as np
from numba import njit

from bench.control import NC as CTRL_NC
from bench.control import ControllerParams, controller_step
from plant_rt import kernel as K
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


def _plant_inputs(params: PlantParams) -> np.ndarray:
    """The kernel input vector held over every period (no schedule, no noise)."""
    u = np.zeros(K.NU)
    e = params.effects
    u[K.U_PRELOAD], u[K.U_BACKLASH], u[K.U_FSCALE] = e.preload_n, e.backlash_m, e.friction_scale
    u[K.U_VSCALE] = e.viscous_scale
    u[K.U_IGAIN] = params.sensors.current_gain
    u[K.U_IOFF] = params.sensors.current_offset_a
    return u


def _delay_periods(params: PlantParams) -> int:
    return int(round(params.effects.sensor_delay_s / params.sim.sync_period_s))


def _x0_true(params: PlantParams, drive: Drive) -> float:
    """Nut position at the start: from the absolute encoder angle when the log has one,
    else the position whose LVDT reading (gain, offset) is the logged initial reading."""
    if drive.x0_true_m is not None:
        return drive.x0_true_m
    se = params.sensors
    return (drive.x0_m - se.lvdt_offset_m) / se.lvdt_gain


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
    plant = initial_plant(params, _x0_true(params, drive))
    x = plant.x.copy()
    meas = np.zeros((n, K.NM))
    dem = np.zeros(n)
    nz = np.zeros((n, 3)) if noise is None else np.ascontiguousarray(noise[:n])
    _closed(x, plant.param_vector, plant._s, _plant_inputs(params), nz,
            drive.sp_pos[:n], drive.sp_spd[:n], drive.mode[:n], cparams.vector(),
            np.zeros(CTRL_NC), _delay_periods(params), meas, dem, drive.applied_load(n))
    return _columns(meas, dem, _delay_periods(params))


def _columns(meas: np.ndarray, dem: np.ndarray, ndelay: int) -> dict[str, np.ndarray]:
    n = len(dem)
    out = {"current_a": meas[:, K.M_CUR].copy(), "current_demand_a": dem}
    idx = np.maximum(np.arange(n) - ndelay, 0) if ndelay else np.arange(n)
    out["motor_speed_rad_s"] = meas[idx, K.M_SPEED]
    out["motor_angle_rad"] = meas[idx, K.M_ANGLE]
    out["position_m"] = meas[idx, K.M_POS]
    return out


@njit(cache=True, error_model="numpy")
def _closed(x, p, s, u0, noise, sp_pos, sp_spd, mode, kvec, cstate, ndelay, meas_out,
            dem_out, fext):  # pragma: no cover - compiled
    n = sp_pos.shape[0]
    m = np.zeros(K.NM)
    u = u0.copy()
    diag = np.zeros(K.NO)
    applied = 0.0
    for k in range(n):
        K.measure(x, s, noise[k], m)
        for j in range(K.NM):
            meas_out[k, j] = m[j]
        kd = k - ndelay if k >= ndelay else 0
        d = controller_step(cstate, kvec, sp_pos[k], sp_spd[k], mode[k],
                            meas_out[kd, K.M_POS], meas_out[kd, K.M_SPEED])
        dem_out[k] = d
        u[K.U_IDEM] = applied
        u[K.U_INOISE] = noise[k, 0]
        u[K.U_FEXT] = fext[k]
        K.advance(x, p, u, diag)
        applied = d
        if not np.isfinite(x[K.OM]):
            for kk in range(k + 1, n):
                for j in range(K.NM):
                    meas_out[kk, j] = np.nan
                dem_out[kk] = np.nan
            return


def open_loop(params: PlantParams, drive: Drive, n: int | None = None) -> dict[str, np.ndarray]:
    """Replay the logged ECU demand (held one period, as the bus does) into the plant."""
    n = len(drive.t) if n is None else min(n, len(drive.t))
    plant = initial_plant(params, _x0_true(params, drive))
    x = plant.x.copy()
    meas = np.zeros((n, K.NM))
    applied = np.zeros(n)
    applied[1:] = np.nan_to_num(drive.demand[:n - 1])
    _replay(x, plant.param_vector, plant._s, _plant_inputs(params), applied, meas,
            np.zeros(n), np.zeros(n), 0, drive.applied_load(n))
    return _columns(meas, applied, _delay_periods(params))


def mechanics_replay(params: PlantParams, drive: Drive, speed_meas: np.ndarray,
                     segment: int = 50, n: int | None = None) -> dict[str, np.ndarray]:
    """Replay the logged demand in segments of `segment` periods, re-synchronising the
    screw speed (and encoder filter) to the measured motor speed at each segment start.

    The residual of motor speed against this replay is the mechanics path's gap
    (current -> motor speed) with a bounded drift. `speed_meas` should be lightly
    smoothed (noise enters at each re-synchronisation).
    """
    n = len(drive.t) if n is None else min(n, len(drive.t))
    plant = initial_plant(params, _x0_true(params, drive))
    x = plant.x.copy()
    meas = np.zeros((n, K.NM))
    applied = np.zeros(n)
    applied[1:] = np.nan_to_num(drive.demand[:n - 1])
    # the measured speed is sensor_delay old: re-synchronise on the sample that describes now
    nd = _delay_periods(params)
    sync = np.empty(n)
    sync[:n - nd] = speed_meas[nd:n] if nd else speed_meas[:n]
    if nd:
        sync[n - nd:] = speed_meas[n - 1]
    _replay(x, plant.param_vector, plant._s, _plant_inputs(params), applied, meas,
            sync / params.sensors.encoder_gain, np.ones(n), segment, drive.applied_load(n))
    return _columns(meas, applied, nd)


@njit(cache=True, error_model="numpy")
def _replay(x, p, s, u0, applied, meas_out, w_sync, w_ok, segment, fext):  # pragma: no cover
    n = applied.shape[0]
    m = np.zeros(K.NM)
    u = u0.copy()
    diag = np.zeros(K.NO)
    zero = np.zeros(3)
    tau = p[K.P_TAU]
    kin = p[K.P_LEAD] / (2.0 * math.pi)
    for k in range(n):
        if segment > 0 and k % segment == 0 and w_ok[k] > 0.0:
            om = w_sync[k] * tau
            x[K.OM] = om
            x[K.V1] = kin * om
            x[K.V2] = kin * om
            moving = 1.0 if abs(w_sync[k]) > 0.5 else 0.0
            if moving > 0.0:
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
        K.measure(x, s, zero, m)
        for j in range(K.NM):
            meas_out[k, j] = m[j]
        u[K.U_IDEM] = applied[k]
        u[K.U_FEXT] = fext[k]
        K.advance(x, p, u, diag)
        if not np.isfinite(x[K.OM]):
            for kk in range(k + 1, n):
                for j in range(K.NM):
                    meas_out[kk, j] = np.nan
            return


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
