"""In-process harness: a profile run on the full plant with the ECU in the one compiled
closed loop (`bench.sim.loop.ecu_on_plant`), with the bus timing.

This module prepares the per-period inputs (set-points, degradation schedule, noise,
external force) and names the outputs; the loop itself, with its timing (the demand of
SYNC k applied during period k+1, the sensor delay, the stop on a non-finite state), is
`bench.sim.loop`. A lockstep bus run of the same scenario gives the same trace
(tests/integration).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench import BenchError
from bench.profiles.catalog import Profile
from bench.signals.trace import Trace
from bench.sim.control import NC as CTRL_NC
from bench.sim.control import ControllerParams
from bench.sim.loop import (
    NT,
    TRUTH_FROM_STATE,
    delay_periods,
    ecu_on_plant,
    ecu_reference,
    measured_columns,
    no_columns,
    run_chunks,
)
from plant_rt import kernel as K
from plant_rt.aero import gust_sequence
from plant_rt.model import Plant, load_noise_seed, schedule_at, separate_current_channel
from plant_rt.params import PlantParams


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
    u[:, K.U_ISEP] = separate_current_channel(params)
    if ext_force_n is not None:
        u[:, K.U_FEXT] = ext_force_n(t)
    if params.load.kind == "aero":
        u[:, K.U_GUST] = gust_sequence(params, n)
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
    st = np.zeros((n, NT))
    ndelay = delay_periods(params)
    bar = None
    on_chunk = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=round(n * params.sim.sync_period_s, 3), unit="sim s",
                   desc=profile.name, leave=False)

        def on_chunk(periods: int) -> None:
            bar.update(round(periods * params.sim.sync_period_s, 3))
    # chunks keep the progress bar moving; the loop state (x, controller, applied
    # demand) carries across chunk boundaries so chunking does not change the result.
    # The loop writes the applied demand and noise into the rows of ri.u.
    n = run_chunks(ecu_on_plant, plant.x, plant.param_vector, plant.sensor_vector,
                   no_columns(n), ri.u, ri.noise, ecu_reference(ri.sp_pos, ri.sp_spd, ri.mode),
                   cparams.vector(), np.zeros(CTRL_NC), ndelay, meas, dem, diag, st,
                   chunk=max(1, int(round(chunk_s / params.sim.sync_period_s))),
                   on_chunk=on_chunk)
    if bar is not None:
        bar.close()
    meta = {"source": "in-process", "profile": profile.name, "profile_kwargs": profile.kwargs,
            "fundamental_hz": profile.fundamental_hz,
            "params": params.to_dict(), "controller": cparams.__dict__,
            "complete": bool(n == len(ri.t)),
            "wear_volume_m3": float(plant.x[K.WEAR_V])}
    if profile.phases:
        meta["phases"] = [list(ph) for ph in profile.phases]
    return Trace(_columns(ri, n, meas, dem, diag, st, ndelay), meta)


def _columns(ri: RunInputs, n: int, meas: np.ndarray, dem: np.ndarray, diag: np.ndarray,
             st: np.ndarray, ndelay: int) -> dict[str, np.ndarray]:
    """The trace's columns over the first `n` periods (the bus's names and timing)."""
    mc = measured_columns(meas[:n], dem[:n], ndelay)
    cols = {
        "t_s": ri.t[:n],
        "setpoint_position_m": ri.sp_pos[:n],
        "setpoint_speed_rad_s": ri.sp_spd[:n],
        "mode": ri.mode[:n],
        "current_demand_a": dem[:n],
        "current_a": mc["current_a"],
        "motor_speed_rad_s": mc["motor_speed_rad_s"],
        "motor_angle_rad": mc["motor_angle_rad"],
        "position_m": mc["position_m"],
        # the load cell sampled at SYNC k reads the force averaged over period k - 1
        "load_force_n": np.concatenate([[0.0], diag[:n - 1, K.O_FEXT]]) + ri.noise_load[:n],
    }
    for j, name in enumerate(TRUTH_FROM_STATE):
        cols[name] = st[:n, j]
    cols["friction_torque_nm"] = diag[:n, K.O_FRIC_T]
    cols["friction_force_n"] = diag[:n, K.O_FRIC_F]
    cols["reaction_torque_nm"] = diag[:n, K.O_REACT_T]
    cols["ext_force_n"] = diag[:n, K.O_FEXT]
    cols["voltage_v"] = diag[:n, K.O_VOLT]
    cols["current_limited"] = diag[:n, K.O_ILIM]
    # the degradation of each period as the plant applied it (the schedule's, plus
    # Archard wear under wear.kind = archard)
    cols["preload_n"] = diag[:n, K.O_PRELOAD]
    cols["backlash_m"] = diag[:n, K.O_BACKLASH]
    cols["friction_scale"] = diag[:n, K.O_FSCALE]
    return cols
