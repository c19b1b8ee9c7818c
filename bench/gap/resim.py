"""Re-simulation of a logged run, whole loop or one path at a time.

Everything here is driven by logged signals only (never by simulation truth):

- `closed_loop`: the bench's own loop (set-point -> ECU -> plant, the compiled
  `bench.sim.loop.ecu_on_plant` that `bench.sim.harness` runs), driven by the logged set-points
  and mode, and by the logged axial load when the log has a load cell. The ECU demand
  computed at SYNC k is applied by the drive during period k+1, exactly as over the bus.
  With `Drive.cascade` set, an identified generic cascade (`bench.gap.cascade`) takes
  the ECU's place.
- `open_loop`: the logged ECU demand replayed into the plant with the same one-period
  hold (the same loop with the demand from a table; isolates current demand -> current:
  the drive path).
- `current_driven` (`Drive.resim = "measured-current"`, which `closed_loop` then runs):
  no controller; the logged (measured) current is the drive's demand and the mechanics
  are re-started from the measured encoder angle and speed every `RESTART_S`: for logs run
  under a controller the bench does not know.
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

from bench.gap import delays as D
from bench.gap.cascade import NGC, Cascade, cascade_on_plant
from bench.sim.control import NC as CTRL_NC
from bench.sim.control import ControllerParams
from bench.sim.loop import (
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
from plant_rt.model import Plant, separate_current_channel
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
    resim: str = "closed-loop"  # or "measured-current" (RESIMS): what closes the loop
    current_meas: np.ndarray | None = None   # logged current (A), measured-current only
    angle_meas: np.ndarray | None = None     # logged encoder angle (rad), the same
    cascade: Cascade | None = None   # an identified controller in the ECU's place

    def applied_load(self, n: int) -> np.ndarray:
        """External force (N) held over each of the first `n` periods: the load cell's
        reading at SYNC k + 1 is the force averaged over period k (zeros without one)."""
        if self.load_n is None or n == 0:
            return np.zeros(n)
        f = np.nan_to_num(np.asarray(self.load_n[:n], float))
        return np.append(f[1:], f[-1])


RESIMS = ("closed-loop", "measured-current")
"""How a log is re-simulated: the bench's ECU on the plant (closed-loop), or no
controller, the measured current driving the plant (measured-current, `current_driven`)."""
RESTART_S = 0.5
"""measured-current: the mechanics re-start from the measured state this often (s), the
generic rig model's segment (`bench.sim.rigmodel.current_driven`)."""
CURRENT_PASSES = 3
"""measured-current: the demand is corrected by the model current's error against the
measured one and the run repeated (iterative learning), this many runs in all: a PI
current loop lags a ramping back-EMF by ke (dw/dt) / ki (~1.5 A at full acceleration),
which the measured current already holds."""
RESTART_FIT_S = 0.002
"""measured-current: the re-start angle and speed come from a straight line fitted to the
measured encoder angle over +- this (s) (`bench.sim.rigmodel.restart_state`): a few
periods, so a re-start at the onset of a step does not take the step's speed."""


def angle_to_travel(params: PlantParams) -> float:
    """Nut travel per motor radian (m/rad): tau p / 2 pi with `params`' ratio and lead."""
    return params.reducer.ratio * params.screw.lead_m / (2.0 * math.pi)


def initial_plant(params: PlantParams, x0_true_m: float) -> Plant:
    """A plant at rest with the nut at `x0_true_m` (preload seated, stiction held)."""
    plant = Plant(params)
    if x0_true_m:
        dth = x0_true_m * 2.0 * math.pi / params.screw.lead_m
        plant.x[K.TH] += dth
        plant.x[K.TH_HIST:K.TH_HIST + K.NHIST] += dth   # at rest there for ever
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
    u0[K.U_ISEP] = separate_current_channel(params)
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


@dataclass
class Resume:
    """A closed loop's state after its first `k` periods, to run on from there
    (`closed_loop`'s `keep` and `resume`): the plant state, the controller state and the
    measurements and demands so far (the sensor delay reads them)."""
    k: int
    x: np.ndarray
    cstate: np.ndarray
    meas: np.ndarray
    dem: np.ndarray


def _run(entry: Callable[..., int], params: PlantParams, drive: Drive, n: int, aux: np.ndarray,
         noise: np.ndarray, ref: np.ndarray, kvec: np.ndarray, cstate: np.ndarray,
         ndelay: int, final: dict[str, np.ndarray] | None = None,
         keep: dict[str, Resume] | None = None, resume: Resume | None = None
         ) -> tuple[np.ndarray, np.ndarray]:
    """Run `entry` (a `bench.sim.loop` entry point) on the plant at rest at the log's start;
    after a non-finite state the remaining periods are NaN. Returns (meas, demand);
    `final`, when given, receives the plant's last state (``final["x"]``). `keep`, when
    given, receives the state after all periods but the last (``keep["state"]``, a
    `Resume`; the last period's load is the log's next reading, which a longer run
    replaces), and `resume` starts from such a state instead of the start: the periods
    are the same compiled steps on the same state either way (`run_chunks` in two
    spans), so the columns are those of one run from the start."""
    plant = initial_plant(params, _x0_true(params, drive))
    meas = np.zeros((n, K.NM))
    dem = np.zeros(n)
    x = plant.x.copy()
    u = _plant_inputs(params, drive, n)
    diag, truth = np.zeros((n, K.NO)), np.zeros((n, NT))
    pv, sv = plant.param_vector, plant.sensor_vector
    start, applied = 0, 0.0
    if resume is not None and 0 < resume.k < n:
        start = resume.k
        x[:] = resume.x
        cstate[:] = resume.cstate
        meas[:start] = resume.meas
        dem[:start] = resume.dem
        applied = float(resume.dem[start - 1])
    split = n - 1 if keep is not None and start < n - 1 else n
    args = (entry, x, pv, sv, aux, u, noise, ref, kvec, cstate, ndelay, meas, dem, diag, truth)
    got = run_chunks(*args, applied=applied, start=start, stop=split)
    if keep is not None and got == split < n:    # the state kept, then the last period
        keep["state"] = Resume(split, x.copy(), cstate.copy(), meas[:split].copy(),
                               dem[:split].copy())
        got = run_chunks(*args, applied=float(dem[split - 1]), start=split)
    meas[got:] = np.nan
    dem[got:] = np.nan
    if final is not None:
        final["x"] = x
    return meas, dem


def closed_loop(params: PlantParams, drive: Drive, n: int | None = None,
                cparams: ControllerParams | None = None,
                noise: np.ndarray | None = None,
                delays: tuple[int, int] = (0, 0),
                final: dict[str, np.ndarray] | None = None,
                keep: dict[str, Resume] | None = None,
                resume: Resume | None = None) -> dict[str, np.ndarray]:
    """Re-simulate the closed loop over the first `n` periods of `drive`.

    Returns the measured columns (current_a, motor_speed_rad_s, motor_angle_rad,
    position_m, current_demand_a) as the bus would log them, sensor delay included.
    `noise` (n, 3): optional white noise (A, m, rad/s) per SYNC, as the plant draws it.
    `delays`: whole SYNC periods by which the LVDT and the encoder are read later still,
    each alone (`bench.gap.delays`; the measured-current re-simulation has no loop to
    delay them in: they shift its logged columns). `final`: receives the plant's last
    state (``final["x"]``; its energy accounts hold the friction's work, `friction_work`).
    `keep` and `resume` (the closed loop without noise only, `_run`): the state before the
    last period, and a run that goes on from one kept by a shorter run of the same values
    (`bench.gap.problem.Problem._loop_cols`: a fit's optimum on the fit part, then on the
    whole log).
    """
    n = len(drive.t) if n is None else min(n, len(drive.t))
    dl, de = (int(d) for d in delays)
    if drive.resim == "measured-current":
        out = current_driven(params, drive, n, noise)
        return shift_columns(out, dl, de) if dl or de else out
    cparams = cparams or ControllerParams(sample_period_s=params.sim.sync_period_s)
    nz = np.zeros((n, 3)) if noise is None else np.ascontiguousarray(noise[:n])
    nd = delay_periods(params)
    ref = ecu_reference(drive.sp_pos[:n], drive.sp_spd[:n], drive.mode[:n])
    if drive.cascade is not None:
        kv = drive.cascade.vector(params.sim.sync_period_s, angle_to_travel(params))
        entry, cstate = cascade_on_plant, np.zeros(NGC)
        if dl or de:
            entry, kv = D.cascade_split_on_plant, D.with_delays(kv, dl, de)
    else:
        kv, entry, cstate = cparams.vector(), ecu_on_plant, np.zeros(CTRL_NC)
        if dl or de:
            entry, kv = D.ecu_split_on_plant, D.with_delays(kv, dl, de)
    if noise is not None:
        keep = resume = None
    meas, dem = _run(entry, params, drive, n, no_columns(n), nz, ref, kv, cstate, nd, final,
                     keep, resume)
    if dl or de:
        return D.split_columns(meas, dem, nd, dl, de)
    return _columns(meas, dem, nd)


def shift_columns(cols: dict[str, np.ndarray], lvdt_periods: int, encoder_periods: int
                  ) -> dict[str, np.ndarray]:
    """Logged columns with the LVDT and the encoder (angle, speed) read `lvdt_periods` and
    `encoder_periods` SYNC periods late (the first sample repeated)."""
    out = dict(cols)
    for names, d in ((("position_m",), lvdt_periods),
                     (("motor_speed_rad_s", "motor_angle_rad"), encoder_periods)):
        if d <= 0:
            continue
        for c in names:
            y = cols[c]
            out[c] = np.concatenate([np.full(min(d, len(y)), y[:1]), y[:-d]])[:len(y)] \
                if len(y) else y
    return out


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
        # a count-difference speed estimator: the angles of a constant speed
        t_sync = p[K.P_DT] * p[K.P_NSUB]
        for j in range(K.NHIST):
            x[K.TH_HIST + j] = x[K.TH] - (j + 1) * t_sync * x[K.OM]


@njit(cache=True, nogil=True, error_model="numpy")
def table_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                   diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """The logged demand (`bench.sim.loop.table_control`) on the full plant, re-synchronised
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


# --- the measured current drives the plant ------------------------------------------------
# aux rows of the current-driven replay: re-start now (1/0), motor angle (rad) and speed
# (rad/s) to re-start from
C_SYNC, C_ANGLE, C_W = 0, 1, 2


@njit(inline="always", error_model="numpy")
def restart(x, p, aux, kk):  # pragma: no cover - compiled
    """Where aux[kk, C_SYNC] says so, move the mechanics to the measured motor angle and
    speed: the screw angle, the nut halves, balls and LVDT state by the same travel (their
    deflections kept), the speeds of a rigid screw (eq. 5.8, 5.26), the encoder states and
    the count history of that constant speed; moving (> 0.5 rad/s) frees the stiction
    states, else the screw is held."""
    if aux[kk, C_SYNC] > 0.0:
        tau = p[K.P_TAU]
        kin = p[K.P_LEAD] / (2.0 * math.pi)
        th = aux[kk, C_ANGLE] * tau
        dx = kin * (th - x[K.TH])
        x[K.TH] = th
        x[K.X1] += dx
        x[K.X2] += dx
        x[K.ZB1] += dx * p[K.P_G]
        x[K.ZB2] += dx * p[K.P_G]
        x[K.LY] += dx
        moving = abs(aux[kk, C_W]) > 0.5
        om = aux[kk, C_W] * tau if moving else 0.0
        x[K.OM] = om
        x[K.V1] = kin * om
        x[K.V2] = kin * om
        x[K.LYD] = kin * om
        st = 0.0 if moving else 1.0
        x[K.STS] = st
        x[K.STN1] = st
        x[K.STN2] = st
        x[K.EY] = om / tau
        x[K.EYD] = 0.0
        t_sync = p[K.P_DT] * p[K.P_NSUB]
        for j in range(K.NHIST):
            x[K.TH_HIST + j] = th - (j + 1) * t_sync * om


@njit(cache=True, nogil=True, error_model="numpy")
def current_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                     diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """A demand table (the measured current) on the full plant, re-started where aux
    says so."""
    return run_loop(restart, kernel_measure, kernel_truth, kernel_advance, table_control,
                    x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                    diag_out, truth_out, applied, k0)


def current_driven(params: PlantParams, drive: Drive, n: int | None = None,
                   noise: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The plant driven by the logged current instead of a controller (a log
    run under a controller the bench does not know).

    The drive's demand over period k is the current measured at SYNC k + 1, corrected
    by the model current's error of a previous run (`CURRENT_PASSES`), so the model's
    current follows the measured one; the
    mechanics re-start every `RESTART_S` from the measured encoder angle and its speed
    (a straight line over +- `RESTART_FIT_S`, taken `sensor_delay` samples later: the
    sample that describes the re-start instant). Between re-starts the model runs open
    loop, so its residual is the mechanics' and sensors' gap over half a second. The
    current is an input here: its residual only shows the drive's tracking.
    Returns the columns of `closed_loop` (current_demand_a: the replayed demand)."""
    from bench.sim.rigmodel import restart_state
    n = len(drive.t) if n is None else min(n, len(drive.t))
    if drive.current_meas is None or drive.angle_meas is None:
        raise ValueError("a measured-current re-simulation needs the logged current_a and "
                         "motor_angle_rad")
    cur = np.nan_to_num(np.asarray(drive.current_meas[:n], float))
    # the table's row k is applied over period k + 1 (bench.sim.loop): the current at k + 2
    table = np.append(cur[2:], np.full(min(2, n), cur[-1])).reshape(n, 1)
    nd = delay_periods(params)
    dt = params.sim.sync_period_s
    seg = max(2, int(round(RESTART_S / dt)))
    starts = np.arange(0, n, seg)
    ang = np.asarray(drive.angle_meas[:n], float)
    th, w = restart_state(np.arange(n) * dt, ang, max(1, int(round(RESTART_FIT_S / dt))),
                          np.minimum(starts + nd, n - 1))
    aux = np.zeros((n, 3))
    aux[starts, C_SYNC] = 1.0
    aux[starts, C_ANGLE] = th
    aux[starts, C_W] = w
    nz = np.zeros((n, 3)) if noise is None else np.ascontiguousarray(noise[:n])
    for it in range(CURRENT_PASSES):
        meas, _ = _run(current_on_plant, params, drive, n, aux, nz, table, np.zeros(0),
                       np.zeros(0), 0)
        if it + 1 < CURRENT_PASSES:     # the drive's tracking error, added to the demand
            err = np.nan_to_num(cur - (meas[:, K.M_CUR] - nz[:, 0]))
            table[:, 0] += np.append(err[2:], np.zeros(min(2, n)))
    applied = np.zeros(n)
    applied[1:] = table[:-1, 0]
    return _columns(meas, applied, nd)


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
    x = encoder_travel(angle_rad, x0_m, params)
    return lvdt_dynamics(x, dt, params)


def lvdt_dynamics(x: np.ndarray, dt: float, params: PlantParams) -> np.ndarray:
    """The nut travel `x` through the model's LVDT conditioning: the second-order filter
    of eq. 5.1, or a first-order lag when `sensors.lvdt_time_constant_s` > 0."""
    se = params.sensors
    if se.lvdt_time_constant_s > 0.0:
        return first_order(x, dt, se.lvdt_time_constant_s)
    return second_order(x, dt, se.lvdt_natural_rad_s, se.lvdt_damping)


def encoder_speed_from_angle(angle_rad: np.ndarray, params: PlantParams,
                             dt: float) -> np.ndarray:
    """The encoder speed (rad/s) the nominal sensor predicts from the measured angle:
    the angle's derivative through the encoder dynamics (eq. 5.1), or the count difference
    over `sensors.encoder_speed_window` periods when the drive computes it so."""
    se = params.sensors
    win = se.encoder_speed_window
    if win > 0:    # the count difference over `win` periods (the angle is the counts)
        old = np.concatenate([np.full(min(win, len(angle_rad)), angle_rad[:1]),
                              angle_rad[:-win]])[:len(angle_rad)] if len(angle_rad) else angle_rad
        return (angle_rad - old) / (win * dt)
    w = np.gradient(angle_rad, dt) if len(angle_rad) > 1 else np.zeros_like(angle_rad)
    # the central difference is centred half a sample late relative to the filter input
    return second_order(w, dt, se.encoder_natural_rad_s, se.encoder_damping)


def warm() -> None:
    """Load the compiled closed loops (numba's cache: the ECU on the plant, and with the
    sensors delayed apart) by a few periods of a still drive: a worker process that does
    it while the diagnosis localises the gap does not pay it at its first fit."""
    n = 4
    z = np.zeros(n)
    drive = Drive(np.arange(n) * 1e-3, z, z, np.ones(n), np.full(n, np.nan), 0.0, 0.0)
    params = PlantParams().with_dict({**FAST, "sensors.noise": False})
    closed_loop(params, drive)
    closed_loop(params, drive, delays=(1, 0))


def friction_work(params: PlantParams, drive: Drive, n: int | None = None,
                  delays: tuple[int, int] = (0, 0)) -> float:
    """The work (J) the friction of `params` dissipates over the closed-loop re-simulation
    of the first `n` periods: the screw's friction torque (eq. 5.13-5.14, motor, reducer
    and support reflected to the screw) and the nut halves' friction forces (eq. 5.31)
    times their speeds, as the kernel accounts them (`E_FRS`, `E_FRN`). Whatever the law,
    the ratio of two models' work on one log is the factor their friction differs by
    along that motion."""
    final: dict[str, np.ndarray] = {}
    if drive.resim == "measured-current":
        return float("nan")
    closed_loop(params, drive, n, delays=delays, final=final)
    x = final.get("x")
    return float(x[K.E_FRS] + x[K.E_FRN]) if x is not None else float("nan")



def load_note(drive: Drive, model: str) -> str:
    """How the re-simulation of `model` treats the axial load of `drive`'s log."""
    f = drive.load_n
    if f is None:
        return "no load cell in the log (load_force_n): zero axial load assumed"
    peak = float(np.nanmax(np.abs(f))) if len(f) else 0.0
    if model != "plant":
        return (f"logged load up to {peak:.0f} N is not an input of the monitoring model "
                "(eq. 6.1, no load term): its effect is part of the gap")
    return f"axial load replayed from the load cell (load_force_n, up to {peak:.0f} N)"
