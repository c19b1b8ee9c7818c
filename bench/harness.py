"""In-process harness: the compiled plant step and the ECU controller in one compiled loop.

The coupling is the bus's: at SYNC k the plant's sensors are sampled (TPDOs), the ECU
computes a demand from them, and that demand is applied by the drive during period k+1
(RPDO applied at the next SYNC): one period of delay plus sample-and-hold. A lockstep bus
run of the same scenario gives the same trace (tests/integration).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from bench import BenchError
from bench.control import NC as CTRL_NC
from bench.control import ControllerParams, controller_step
from bench.profiles import Profile
from bench.trace import Trace
from plant_rt import kernel as K
from plant_rt.model import Plant, load_noise_seed, schedule_at
from plant_rt.params import PlantParams

TRUTH_FROM_STATE = ("true_position_m", "true_current_a", "true_motor_speed_rad_s",
                    "motor_torque_nm", "temperature_k")


@dataclass
class RunInputs:
    """Per-period inputs of a run, precomputed (schedules, noise, set-points)."""
    t: np.ndarray
    sp_pos: np.ndarray
    sp_spd: np.ndarray
    mode: np.ndarray
    u: np.ndarray
    noise: np.ndarray
    sched: np.ndarray   # (n, 3): preload N, backlash m, friction scale
    noise_load: np.ndarray  # (n,): load cell noise (N)


def run_inputs(profile: Profile, params: PlantParams, duration_s: float | None = None,
               mode_override: np.ndarray | None = None,
               ext_force_n: Callable[[np.ndarray], np.ndarray] | None = None) -> RunInputs:
    """Inputs of every SYNC period of `profile` under `params` (noise stream as Plant's).
    `ext_force_n(t)`: an axial force (N) held over the period starting at t, added to the
    load profile of `params`."""
    ts = params.sim.sync_period_s
    dur = profile.duration_s if duration_s is None else duration_s
    n = int(round(dur / ts))
    if n < 1:
        raise BenchError(f"run of {dur} s is shorter than one SYNC period")
    t = np.arange(n) * ts
    sp_pos, sp_spd = profile.setpoints(t)
    mode = np.full(n, float(profile.mode)) if mode_override is None else mode_override
    sched = np.array([schedule_at(params, tk) for tk in t]) if params.schedule.kind != "none" \
        else np.tile(schedule_at(params, 0.0), (n, 1))
    u = np.zeros((n, K.NU))
    u[:, K.U_PRELOAD], u[:, K.U_BACKLASH], u[:, K.U_FSCALE] = sched.T
    u[:, K.U_VSCALE] = params.effects.viscous_scale
    u[:, K.U_IGAIN] = params.sensors.current_gain
    u[:, K.U_IOFF] = params.sensors.current_offset_a
    if ext_force_n is not None:
        u[:, K.U_FEXT] = ext_force_n(t)
    se = params.sensors
    noise = np.zeros((n, 3))
    noise_load = np.zeros(n)
    if se.noise:
        z = np.random.default_rng(se.noise_seed).standard_normal((n + 1, 3))[:n]
        noise[:] = z * np.array([se.current_noise_a, se.position_noise_m, se.speed_noise_rad_s])
        noise_load[:] = (np.random.default_rng(load_noise_seed(params)).standard_normal(n + 1)[:n]
                         * se.load_noise_n)
    return RunInputs(t, sp_pos, sp_spd, mode, u, noise, sched, noise_load)


def simulate(profile: Profile, params: PlantParams | None = None,
             cparams: ControllerParams | None = None, duration_s: float | None = None,
             progress: bool = False, chunk_s: float = 1.0,
             ext_force_n: Callable[[np.ndarray], np.ndarray] | None = None) -> Trace:
    """Run `profile` on the plant with the ECU controller in-process; returns a Trace.

    `params` are applied with the profile's own overrides (e.g. the RUL schedule).
    With `progress`, a tqdm bar advances every `chunk_s` of simulated time.
    `ext_force_n(t)`: an extra axial force (N) per SYNC period on top of `params.load`
    (in-process only; the load cell reads it like any other external force).
    """
    params = (params or PlantParams())
    if profile.params_overrides:
        params = params.with_dict(profile.params_overrides)
    cparams = cparams or ControllerParams(sample_period_s=params.sim.sync_period_s)
    if not math.isclose(cparams.sample_period_s, params.sim.sync_period_s):
        raise BenchError("controller sample period and plant SYNC period differ")
    plant = Plant(params)
    ri = run_inputs(profile, params, duration_s, ext_force_n=ext_force_n)
    n = len(ri.t)
    meas = np.zeros((n, K.NM))
    dem = np.zeros(n)
    diag = np.zeros((n, K.NO))
    st = np.zeros((n, len(TRUTH_FROM_STATE)))
    kvec = cparams.vector()
    cstate = np.zeros(CTRL_NC)
    ndelay = int(round(params.effects.sensor_delay_s / params.sim.sync_period_s))
    chunk = max(1, int(round(chunk_s / params.sim.sync_period_s)))
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=round(n * params.sim.sync_period_s, 3), unit="sim s",
                   desc=profile.name, leave=False)
    done = 0
    applied_carry = 0.0
    # chunks keep the progress bar moving; the loop state (x, controller, applied
    # demand) carries across chunk boundaries so chunking does not change the result.
    while done < n:
        k1 = min(n, done + chunk)
        sl = slice(done, k1)
        got = _run_chunk(plant.x, plant.param_vector, plant._s, ri, sl, kvec, cstate,
                         ndelay, meas, dem, diag, st, applied_carry)
        applied_carry = dem[k1 - 1]
        if bar is not None:
            bar.update(round((k1 - done) * params.sim.sync_period_s, 3))
        if got < k1 - done:
            n = done + got
            break
        done = k1
    if bar is not None:
        bar.close()
    cols = {
        "t_s": ri.t[:n],
        "setpoint_position_m": ri.sp_pos[:n],
        "setpoint_speed_rad_s": ri.sp_spd[:n],
        "mode": ri.mode[:n],
        "current_demand_a": dem[:n],
        "current_a": meas[:n, K.M_CUR],
        "motor_speed_rad_s": meas[:n, K.M_SPEED],
        "motor_angle_rad": meas[:n, K.M_ANGLE],
        "position_m": meas[:n, K.M_POS],
        # the load cell sampled at SYNC k reads the force averaged over period k - 1
        "load_force_n": np.concatenate([[0.0], diag[:n - 1, K.O_FEXT]]) + ri.noise_load[:n],
    }
    if ndelay:
        idx = np.maximum(np.arange(n) - ndelay, 0)
        for c, j in (("motor_speed_rad_s", K.M_SPEED), ("motor_angle_rad", K.M_ANGLE),
                     ("position_m", K.M_POS)):
            cols[c] = meas[idx, j]
    for j, name in enumerate(TRUTH_FROM_STATE):
        cols[name] = st[:n, j]
    cols["friction_torque_nm"] = diag[:n, K.O_FRIC_T]
    cols["friction_force_n"] = diag[:n, K.O_FRIC_F]
    cols["reaction_torque_nm"] = diag[:n, K.O_REACT_T]
    cols["ext_force_n"] = diag[:n, K.O_FEXT]
    cols["voltage_v"] = diag[:n, K.O_VOLT]
    cols["current_limited"] = diag[:n, K.O_ILIM]
    cols["preload_n"], cols["backlash_m"], cols["friction_scale"] = ri.sched[:n].T
    meta = {"source": "in-process", "profile": profile.name, "profile_kwargs": profile.kwargs,
            "fundamental_hz": profile.fundamental_hz,
            "params": params.to_dict(), "controller": cparams.__dict__,
            "complete": bool(n == len(ri.t))}
    return Trace(cols, meta)


def _run_chunk(x, p, s, ri: RunInputs, sl: slice, kvec, cstate, ndelay, meas, dem, diag, st,
               applied: float) -> int:
    """Run periods `sl` in the compiled loop, the first one with the carried demand.

    The output arrays are whole-run arrays, so the sensor delay reads history across
    chunk boundaries exactly."""
    k0, k1 = sl.start, sl.stop
    u = ri.u[k0:k1].copy()
    got = _closed_loop_from(x, p, s, u, ri.noise[k0:k1], ri.sp_pos[k0:k1], ri.sp_spd[k0:k1],
                            ri.mode[k0:k1], kvec, cstate, ndelay, meas, dem, diag, st,
                            applied, k0)
    return got


@njit(cache=True, error_model="numpy")
def _closed_loop_from(x, p, s, u_seq, noise, sp_pos, sp_spd, mode, kvec, cstate, ndelay,
                      meas_out, dem_out, diag_out, state_out, applied, k0):  # pragma: no cover
    n = sp_pos.shape[0]
    m = np.zeros(K.NM)
    for kk in range(n):
        k = k0 + kk
        K.measure(x, s, noise[kk], m)
        for j in range(K.NM):
            meas_out[k, j] = m[j]
        kd = k - ndelay if k >= ndelay else 0
        d = controller_step(cstate, kvec, sp_pos[kk], sp_spd[kk], mode[kk],
                            meas_out[kd, K.M_POS], meas_out[kd, K.M_SPEED])
        dem_out[k] = d
        state_out[k, 0] = 0.5 * (x[K.X1] + x[K.X2])
        state_out[k, 1] = x[K.I]
        state_out[k, 2] = x[K.OM] / p[K.P_TAU]
        state_out[k, 3] = x[K.TQ]
        state_out[k, 4] = x[K.TEMP]
        u = u_seq[kk]
        u[K.U_IDEM] = applied
        u[K.U_INOISE] = noise[kk, 0]
        K.advance(x, p, u, diag_out[k])
        applied = d
        if not np.isfinite(x[K.OM]):
            return kk + 1
    return n
