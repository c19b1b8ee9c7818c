"""The monitoring model of thesis section 6.1 (eq. 6.1-6.2): the nominal actuator.

What it keeps from the plant (`plant_rt`, chapter 5), with the same parameter values:
- the drive's current PI (same gains, the same clamped PI law `plant_rt.pi`), without
  PWM: the inverter gives the set voltage, saturated at the DC bus (the thesis' "carrier
  with an infinite frequency");
- the motor winding (eq. 5.3, Crank-Nicolson as in the plant), the current limit, the
  torque demodulation filter tau_h (eq. 5.4) and the reducer C_m = eta T_M / tau (eq. 5.7);
- the sensors (eq. 5.1-5.2): LVDT and encoder second order, current sensor first order,
  encoder angle quantised to the same counts, so its outputs are the measured columns;
- the ECU controller (`bench.sim.control.controller_step`, same speed PI gains) at the SYNC
  rate in the bench's one closed loop (`bench.sim.loop`, as the harness): the demand computed
  at SYNC k is applied by the drive during period k+1.

What it replaces: the whole screw (balls, contacts, backlash, preload, double nut) by a
rigid screw-nut coupling (eq. 6.1-6.2):

    C_m - 2 C_f,nom(Omega') = I_eq Omega''          x_n = p / (2 pi) Omega

with I_eq = (I_m + I_r) / tau^2 + I_s (eq. 5.12, screw side) and C_f,nom the plant's
screw friction (eq. 5.13-5.14, C_s = (C_fm + C_fr) / tau + C_fs, Stribeck term, viscous
term, stiction switch of fig. 5.17) without the rolling term, counted twice for screw and
nut as eq. 6.1 does. Known differences from the plant it stands for (documented in
docs/hums.md): the plant's nut friction has no Stribeck term and reaches the screw through
the eq. 5.10 lever (0.906 of p/2pi), so the plant's friction at the screw is 1.906 C_s at
cruise and 2.006 C_s near zero speed against the monitor's 2 C_s and 2.2 C_s (5 % and 9 %
lower); the reaction torque and the finite contact stiffness are absent (thesis section
6.1 says the same).

I_eq, C_s and the viscous coefficient are the plant's own (`plant_rt.model`).

Units SI: nut position m, screw angle rad, motor speed rad/s, current A, time s.
The monitor never reads simulation truth; it is driven by set-points and mode only.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np

from bench import BenchError
from bench.core.paramset import ParamSet
from bench.profiles.catalog import Profile
from bench.signals.trace import Trace
from bench.sim.control import NC as CTRL_NC
from bench.sim.control import THESIS_SET_GAIN_V_PER_M, ControllerParams
from bench.sim.loop import ecu_control, ecu_reference, no_columns, no_prepare, run_chunks, run_loop
from plant_rt import kernel as K
from plant_rt.jit import njit
from plant_rt.model import current_ki, equivalent_inertia, static_friction, viscous_friction
from plant_rt.params import P, PlantParams, resolve
from plant_rt.pi import clamped_pi

# --- state vector ------------------------------------------------------------------------
(S_I, S_CI, S_IM, S_TQ, S_OM, S_TH, S_LY, S_LYD, S_EY, S_EYD, S_STUCK, S_T) = range(12)
NXM = 12
# --- parameter vector --------------------------------------------------------------------
(Q_R, Q_L, Q_KE, Q_KT, Q_IMAX, Q_VDC, Q_TAUH, Q_TAUC, Q_TAU, Q_ETA, Q_JEQ, Q_CS, Q_STRA,
 Q_STRV, Q_CVISC, Q_LEAD, Q_LZETA, Q_LSIG, Q_EZETA, Q_ESIG, Q_KPI, Q_KII, Q_DT, Q_NSUB,
 Q_COUNTS, Q_FFAC) = range(26)
NQM = 26
TWO_PI = 2.0 * math.pi
_NO_SENSORS = np.zeros(0)   # the monitor's measure reads its gains from q

def _as_plant(name: str, doc: str = "") -> Any:
    """A monitor field with the plant parameter `name`'s default, unit, range and source."""
    i = resolve(name)
    return P(i.default, i.unit, i.min, i.max, doc or i.doc, f"{i.source} (as {name})")


_NOMINAL = PlantParams()


@dataclass(frozen=True)
class ThesisMonitorGains(ParamSet):
    """The monitoring model's position gains the thesis prints (thesis units, (rad/s)/V,
    with K_SET = 285.7 V/m: `bench.sim.control.THESIS_SET_GAIN_V_PER_M`)."""
    _group: ClassVar[str] = "monitor_gains"
    start_thesis_units: float = P(20.0, "(rad/s)/V", 0.0, 1e5,
                                  "the first attempt of the thesis' fminsearch",
                                  "section 6.3 (fminsearch start)")
    fitted_thesis_units: float = P(663.0, "(rad/s)/V", 0.0, 1e5, "the thesis' k_p,opt",
                                   "section 6.3, row H1")


THESIS_GAINS = ThesisMonitorGains()
THESIS_START_GAIN = THESIS_GAINS.start_thesis_units
"""The first attempt of the thesis' fminsearch (thesis units, (rad/s)/V)."""
THESIS_FITTED_GAIN = THESIS_GAINS.fitted_thesis_units
"""The thesis' k_p,opt (thesis units), row H1."""


@dataclass(frozen=True)
class MonitorParams(ParamSet):
    """Parameters of the monitoring model (SI, thesis symbols in the docs), with units,
    ranges and sources as the plant's (`bench.core.paramset`).

    Build it from a plant parameter set with `from_plant`, so the nominal values are the
    plant's tables 5.1-5.4; only `friction_factor` (eq. 6.1's 2) and the integration step
    are the monitor's own. The defaults are `from_plant(PlantParams())`'s.
    """
    _group: ClassVar[str] = "monitor"
    resistance_ohm: float = _as_plant("motor.resistance_ohm")                 # R
    inductance_h: float = _as_plant("motor.inductance_h")                     # L
    ke_v_s_per_rad: float = _as_plant("motor.ke_v_s_per_rad")                 # k_e
    kt_nm_per_a: float = _as_plant("motor.kt_nm_per_a")                       # k_t
    current_max_a: float = _as_plant("motor.current_max_a")                   # i_max
    supply_voltage_v: float = _as_plant("motor.supply_voltage_v")             # V_a
    demod_time_constant_s: float = _as_plant("motor.demod_time_constant_s")   # tau_h
    current_sensor_time_constant_s: float = _as_plant(
        "sensors.current_time_constant_s")                                    # tau_c
    ratio: float = _as_plant("reducer.ratio")                     # tau (screw / motor speed)
    efficiency: float = _as_plant("reducer.efficiency")                       # eta
    inertia_kg_m2: float = P(equivalent_inertia(_NOMINAL), "kg m^2", 0.0, 1e4,
                             "equivalent inertia I_eq, screw side", "eq. 5.12 (plant tables)")
    static_friction_nm: float = P(static_friction(_NOMINAL), "N m", 0.0, 1e6,
                                  "static friction C_s, screw side", "eq. 5.14 (plant tables)")
    stribeck_amplitude: float = _as_plant("screw.stribeck_amplitude")
    stribeck_velocity_rad_s: float = _as_plant("screw.stribeck_velocity_rad_s")
    viscous_friction_nm_s: float = P(viscous_friction(_NOMINAL), "N m s/rad", 0.0, 1e6,
                                     "viscous coefficient c_sm + c_sr (divided by tau with "
                                     "the screw speed)", "eq. 5.13 (table 5.4)")
    lead_m: float = _as_plant("screw.lead_m")                                 # p
    lvdt_damping: float = _as_plant("sensors.lvdt_damping")
    lvdt_natural_rad_s: float = _as_plant("sensors.lvdt_natural_rad_s")
    encoder_damping: float = _as_plant("sensors.encoder_damping")
    encoder_natural_rad_s: float = _as_plant("sensors.encoder_natural_rad_s")
    current_kp_v_per_a: float = _as_plant("drive.current_kp_v_per_a")         # as the drive
    current_ki_v_per_as: float = _as_plant("drive.current_ki_v_per_as")
    encoder_counts_per_rev: int = _as_plant("sensors.encoder_counts_per_rev")
    sync_period_s: float = _as_plant("sim.sync_period_s")
    friction_factor: float = P(2.0, "-", 0.0, 100.0, "screw and nut friction factor",
                               "eq. 6.1")
    substep_s: float = P(20e-6, "s", 1e-9, 1.0, "integration step (at most sync_period_s)",
                         "chosen (as the plant's averaged-PWM step)")

    @classmethod
    def from_plant(cls, params: PlantParams | None = None, **overrides: Any) -> MonitorParams:
        """The nominal monitor for `params` (its effects, load and noise are ignored)."""
        p = params or PlantParams()
        m, r, s, se, d = p.motor, p.reducer, p.screw, p.sensors, p.drive
        tau = r.ratio
        mp = cls(
            resistance_ohm=m.resistance_ohm, inductance_h=m.inductance_h,
            ke_v_s_per_rad=m.ke_v_s_per_rad, kt_nm_per_a=m.kt_nm_per_a,
            current_max_a=m.current_max_a, supply_voltage_v=m.supply_voltage_v,
            demod_time_constant_s=m.demod_time_constant_s,
            current_sensor_time_constant_s=se.current_time_constant_s,
            ratio=tau, efficiency=r.efficiency,
            inertia_kg_m2=equivalent_inertia(p),                       # eq. 5.12
            static_friction_nm=static_friction(p),                     # eq. 5.14
            stribeck_amplitude=s.stribeck_amplitude,
            stribeck_velocity_rad_s=s.stribeck_velocity_rad_s,
            viscous_friction_nm_s=viscous_friction(p),                 # eq. 5.13
            lead_m=s.lead_m, lvdt_damping=se.lvdt_damping,
            lvdt_natural_rad_s=se.lvdt_natural_rad_s, encoder_damping=se.encoder_damping,
            encoder_natural_rad_s=se.encoder_natural_rad_s,
            current_kp_v_per_a=d.current_kp_v_per_a, current_ki_v_per_as=current_ki(p),
            encoder_counts_per_rev=se.encoder_counts_per_rev,
            sync_period_s=p.sim.sync_period_s)
        return replace(mp, **overrides) if overrides else mp

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.substep_s <= 0 or self.substep_s > self.sync_period_s:
            raise BenchError("monitor substep_s must be in (0, sync_period_s]")

    def vector(self) -> np.ndarray:
        q = np.zeros(NQM)
        q[Q_R], q[Q_L], q[Q_KE], q[Q_KT] = (self.resistance_ohm, self.inductance_h,
                                            self.ke_v_s_per_rad, self.kt_nm_per_a)
        q[Q_IMAX], q[Q_VDC] = self.current_max_a, self.supply_voltage_v
        q[Q_TAUH], q[Q_TAUC] = self.demod_time_constant_s, self.current_sensor_time_constant_s
        q[Q_TAU], q[Q_ETA], q[Q_JEQ] = self.ratio, self.efficiency, self.inertia_kg_m2
        q[Q_CS], q[Q_STRA], q[Q_STRV] = (self.static_friction_nm, self.stribeck_amplitude,
                                         self.stribeck_velocity_rad_s)
        q[Q_CVISC], q[Q_LEAD] = self.viscous_friction_nm_s, self.lead_m
        q[Q_LZETA], q[Q_LSIG] = self.lvdt_damping, self.lvdt_natural_rad_s
        q[Q_EZETA], q[Q_ESIG] = self.encoder_damping, self.encoder_natural_rad_s
        q[Q_KPI], q[Q_KII] = self.current_kp_v_per_a, self.current_ki_v_per_as
        nsub = max(1, round(self.sync_period_s / self.substep_s))
        q[Q_DT], q[Q_NSUB] = self.sync_period_s / nsub, nsub
        q[Q_COUNTS] = self.encoder_counts_per_rev
        q[Q_FFAC] = self.friction_factor
        return q


# --- compiled core -------------------------------------------------------------------------

@njit(cache=True, inline="always", error_model="numpy")
def _sign(v: float) -> float:
    return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)


@njit(cache=True, error_model="numpy")
def monitor_advance(x: np.ndarray, q: np.ndarray, idem: float) -> None:
    """Integrate the monitor over one SYNC period holding the current demand `idem` (A)."""
    dt = q[Q_DT]
    nsub = int(q[Q_NSUB])
    R, L, KE, KT = q[Q_R], q[Q_L], q[Q_KE], q[Q_KT]
    IMAX, VDC = q[Q_IMAX], q[Q_VDC]
    tau, eta, jeq = q[Q_TAU], q[Q_ETA], q[Q_JEQ]
    ff = q[Q_FFAC]
    CS, STRA, STRV = q[Q_CS], q[Q_STRA], q[Q_STRV]
    CVISC = q[Q_CVISC]
    a_c = 1.0 - math.exp(-dt / q[Q_TAUC])
    a_h = 1.0 - math.exp(-dt / q[Q_TAUH])
    kpi, kii = q[Q_KPI], q[Q_KII]
    lz, ls, ez, es = q[Q_LZETA], q[Q_LSIG], q[Q_EZETA], q[Q_ESIG]
    kin = q[Q_LEAD] / TWO_PI
    if idem > IMAX:
        idem = IMAX
    elif idem < -IMAX:
        idem = -IMAX
    c_stat = ff * CS * (1.0 + STRA)
    for _ in range(nsub):
        i = x[S_I]
        om = x[S_OM]
        w_m = om / tau
        # drive: current PI on the measured current, clamping anti-windup, no PWM
        va, x[S_CI] = clamped_pi(idem - x[S_IM], x[S_CI], kpi, kii, dt, VDC)
        # winding (eq. 5.3), Crank-Nicolson as the plant; current limit
        hr = 0.5 * dt * R / L
        i_new = (i * (1.0 - hr) + dt * (va - KE * w_m) / L) / (1.0 + hr)
        if i_new > IMAX:
            i_new = IMAX
        elif i_new < -IMAX:
            i_new = -IMAX
        x[S_I] = i_new
        x[S_IM] += (i_new - x[S_IM]) * a_c                      # eq. 5.2
        x[S_TQ] += (KT * i_new - x[S_TQ]) * a_h                 # eq. 5.4 + demodulation
        # rigid screw (eq. 6.1) with the stiction switch of fig. 5.17
        cm = eta * x[S_TQ] / tau                                # eq. 5.7
        if x[S_STUCK] != 0.0 or om == 0.0:
            if abs(cm) <= c_stat:
                om_new = 0.0
                x[S_STUCK] = 1.0
            else:
                om_new = om + dt * (cm - c_stat * _sign(cm)) / jeq
                x[S_STUCK] = 0.0
        else:
            cf = ff * (CS * (1.0 + STRA * math.exp(-abs(om) / STRV))
                       + CVISC * abs(om) / tau) * _sign(om)     # eq. 5.13-5.14, x2
            om_new = om + dt * (cm - cf) / jeq
            if om_new * om < 0.0:
                om_new = 0.0
                x[S_STUCK] = 1.0 if abs(cm) <= c_stat else 0.0
        x[S_OM] = om_new
        x[S_TH] += dt * om_new
        # sensors (eq. 5.1) on x_n = p / 2 pi Omega (eq. 6.2) and the motor speed
        xn = kin * x[S_TH]
        x[S_LYD] += dt * (ls * ls * (xn - x[S_LY]) - 2.0 * lz * ls * x[S_LYD])
        x[S_LY] += dt * x[S_LYD]
        x[S_EYD] += dt * (es * es * (om_new / tau - x[S_EY]) - 2.0 * ez * es * x[S_EYD])
        x[S_EY] += dt * x[S_EYD]
        x[S_T] += dt


# --- the monitor's parts for the one closed loop (bench.sim.loop) ---------------------------

@njit(inline="always", error_model="numpy")
def monitor_measure(x, q, s, noise, kk, m):  # pragma: no cover - compiled
    """The sensors of eq. 5.1-5.2 in the plant's M_* layout, noise[kk] = (A, m, rad/s):
    current sensor, encoder speed, encoder angle quantised to counts, LVDT (no thermal
    model: M_TEMP is NaN)."""
    m[K.M_CUR] = x[S_IM] + noise[kk, 0]
    m[K.M_SPEED] = x[S_EY] + noise[kk, 2]
    counts = q[Q_COUNTS]
    ang = x[S_TH] / q[Q_TAU]
    m[K.M_ANGLE] = math.floor(ang / TWO_PI * counts) * TWO_PI / counts
    m[K.M_POS] = x[S_LY] + noise[kk, 1]
    m[K.M_TEMP] = math.nan


@njit(inline="always", error_model="numpy")
def monitor_truth(x, q, out, k):  # pragma: no cover - compiled
    """The true nut position x_n = p / 2 pi Omega (eq. 6.2) into out[k, 0]."""
    out[k, 0] = q[Q_LEAD] / TWO_PI * x[S_TH]


@njit(inline="always", error_model="numpy")
def monitor_step(x, q, u, kk, applied, noise, diag, k):  # pragma: no cover - compiled
    """One SYNC period holding `applied` (the monitor never stops the loop)."""
    monitor_advance(x, q, applied)
    return True


@njit(cache=True, error_model="numpy")
def ecu_on_monitor(x, q, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                   diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """The ECU (`bench.sim.loop.ecu_control`) on the monitoring model, with the bus timing."""
    return run_loop(no_prepare, monitor_measure, monitor_truth, monitor_step, ecu_control,
                    x, q, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                    diag_out, truth_out, applied, k0)


# --- Python API -----------------------------------------------------------------------------

def monitor_controller(cparams: ControllerParams | None, position_kp_rad_s_per_m: float,
                       sync_period_s: float = 1e-3) -> ControllerParams:
    """The monitor's ECU: the plant's controller with its own position gain."""
    base = cparams or ControllerParams(sample_period_s=sync_period_s)
    return replace(base, position_kp_rad_s_per_m=float(position_kp_rad_s_per_m))


class Monitor:
    """A monitoring model with state, steppable in chunks of SYNC periods (live use).

    `position_kp_rad_s_per_m`: the monitor's position gain (the fitted one, `fit_gain`);
    `cparams`: the ECU whose speed PI gains and limits the monitor shares.
    """

    def __init__(self, mparams: MonitorParams | None = None,
                 position_kp_rad_s_per_m: float | None = None,
                 cparams: ControllerParams | None = None, x0_m: float = 0.0) -> None:
        self.mparams = mparams or MonitorParams.from_plant()
        kp = (position_kp_rad_s_per_m if position_kp_rad_s_per_m is not None
              else (cparams or ControllerParams()).position_kp_rad_s_per_m)
        self.cparams = monitor_controller(cparams, kp, self.mparams.sync_period_s)
        self._q = self.mparams.vector()
        self._k = self.cparams.vector()
        self.x0_m = x0_m
        self.reset()

    def reset(self) -> None:
        self.x = np.zeros(NXM)
        self.x[S_STUCK] = 1.0
        self.x[S_TH] = self.x0_m * TWO_PI / self.mparams.lead_m
        self.x[S_LY] = self.x0_m
        self._c = np.zeros(CTRL_NC)
        self._applied = 0.0
        self.k = 0

    def run(self, sp_pos: np.ndarray, sp_spd: np.ndarray, mode: np.ndarray,
            noise: np.ndarray | None = None) -> np.ndarray:
        """Advance len(sp_pos) periods with the ECU in the loop (`bench.sim.loop`'s timing: the
        demand of SYNC k applied over period k + 1, carried across calls).

        Returns (n, 6) rows (current_a, motor_speed_rad_s, motor_angle_rad, position_m,
        demand_a, true position m) sampled at SYNC k before the period is integrated.
        `noise` (n, 3): white noise (A, m, rad/s) added to the sensors, zeros for the nominal.
        """
        n = len(sp_pos)
        nz = np.zeros((n, 3)) if noise is None else np.ascontiguousarray(noise[:n], float)
        meas = np.zeros((n, K.NM))      # M_CUR, M_SPEED, M_ANGLE, M_POS: out's first four
        dem = np.zeros(n)
        truth = np.zeros((n, 1))
        run_chunks(ecu_on_monitor, self.x, self._q, _NO_SENSORS, no_columns(n), no_columns(n),
                   nz, ecu_reference(sp_pos, sp_spd, mode), self._k, self._c, 0, meas, dem,
                   no_columns(n), truth, applied=self._applied)
        if n:
            self._applied = float(dem[-1])
        self.k += n
        return np.concatenate([meas[:, :4], dem[:, None], truth], axis=1)


def nominal_columns(t: np.ndarray, sp_pos: np.ndarray, sp_spd: np.ndarray, mode: np.ndarray,
             out: np.ndarray) -> dict[str, np.ndarray]:
    return {"t_s": t, "setpoint_position_m": sp_pos, "setpoint_speed_rad_s": sp_spd,
            "mode": mode, "current_demand_a": out[:, 4], "current_a": out[:, 0],
            "motor_speed_rad_s": out[:, 1], "motor_angle_rad": out[:, 2],
            "position_m": out[:, 3], "true_position_m": out[:, 5]}


def simulate_monitor(profile: Profile, position_kp_rad_s_per_m: float | None = None,
                     mparams: MonitorParams | None = None,
                     cparams: ControllerParams | None = None,
                     duration_s: float | None = None) -> Trace:
    """The nominal trace of `profile` (same column names as `bench.sim.harness.simulate`)."""
    mparams = mparams or MonitorParams.from_plant()
    ts = mparams.sync_period_s
    n = int(round((profile.duration_s if duration_s is None else duration_s) / ts))
    if n < 1:
        raise BenchError("monitor run shorter than one SYNC period")
    t = np.arange(n) * ts
    sp_pos, sp_spd = profile.setpoints(t)
    mode = np.full(n, float(profile.mode))
    mon = Monitor(mparams, position_kp_rad_s_per_m, cparams)
    out = mon.run(sp_pos, sp_spd, mode)
    meta = {"source": "monitor", "profile": profile.name, "profile_kwargs": profile.kwargs,
            "fundamental_hz": profile.fundamental_hz,
            "position_kp_rad_s_per_m": mon.cparams.position_kp_rad_s_per_m}
    return Trace(nominal_columns(t, sp_pos, sp_spd, mode, out), meta)


NOMINAL_DRIVE = ("t_s", "setpoint_position_m", "setpoint_speed_rad_s", "mode")


def nominal_for(trace: Trace, position_kp_rad_s_per_m: float | None = None,
                mparams: MonitorParams | None = None,
                cparams: ControllerParams | None = None) -> Trace:
    """The monitor's nominal trace for the set-points and mode logged in `trace`.

    The monitor starts at rest at the first logged LVDT position (when logged), so a log
    that does not start at zero is compared from the same place.
    """
    trace.require(NOMINAL_DRIVE, "the monitoring model")
    mparams = mparams or MonitorParams.from_plant()
    dt = trace.dt
    if len(trace) > 1 and not math.isclose(dt, mparams.sync_period_s, rel_tol=0.02):
        raise BenchError(f"the trace is sampled every {dt * 1e3:.3g} ms; the monitoring model "
                         f"runs at the SYNC period {mparams.sync_period_s * 1e3:.3g} ms")
    sp_pos = np.nan_to_num(trace["setpoint_position_m"])
    sp_spd = np.nan_to_num(trace["setpoint_speed_rad_s"])
    mode = np.nan_to_num(trace["mode"])
    x0 = 0.0
    if "position_m" in trace and np.isfinite(trace["position_m"][:1]).all():
        x0 = float(trace["position_m"][0])
        if abs(x0) < 20e-6:     # noise-level start: the plant starts at 0
            x0 = 0.0
    mon = Monitor(mparams, position_kp_rad_s_per_m, cparams, x0_m=x0)
    out = mon.run(sp_pos, sp_spd, mode)
    meta = {"source": "monitor", "of": trace.meta.get("source", "?"),
            "fundamental_hz": trace.meta.get("fundamental_hz", float("nan")),
            "position_kp_rad_s_per_m": mon.cparams.position_kp_rad_s_per_m}
    return Trace(nominal_columns(trace.t.copy(), sp_pos, sp_spd, mode, out), meta)


def closed_loop(params: PlantParams, drive: Any, n: int | None = None,
                cparams: ControllerParams | None = None,
                noise: np.ndarray | None = None,
                position_kp_rad_s_per_m: float | None = None) -> dict[str, np.ndarray]:
    """The re-simulation interface of `bench.gap` (`bench.gap.resim.Drive` in): the
    monitor driven by logged set-points and mode, measured columns out."""
    n = len(drive.t) if n is None else min(n, len(drive.t))
    mp = MonitorParams.from_plant(params)
    kp = position_kp_rad_s_per_m
    if kp is None:
        kp = (cparams or ControllerParams()).position_kp_rad_s_per_m
    x0 = getattr(drive, "x0_true_m", None)      # absolute encoder start, when the log has it
    mon = Monitor(mp, kp, cparams, x0_m=float(drive.x0_m if x0 is None else x0))
    out = mon.run(drive.sp_pos[:n], drive.sp_spd[:n], drive.mode[:n], noise)
    return {"current_a": out[:, 0], "current_demand_a": out[:, 4],
            "motor_speed_rad_s": out[:, 1], "motor_angle_rad": out[:, 2],
            "position_m": out[:, 3]}


# --- H1: the Nelder-Mead fit of the position gain ------------------------------------------

@dataclass(frozen=True)
class GainFit:
    """Result of `fit_gain` (row H1). Gains in (rad/s)/m and in thesis units (rad/s)/V."""
    start_thesis_units: float
    gain_rad_s_per_m: float
    rms_residual_m: float          # RMS position difference after the fit
    rms_start_m: float             # ... with the starting gain
    rms_signal_m: float            # RMS of the real position (scale of the residual)
    plant_gain_rad_s_per_m: float  # the plant's ECU position gain, for comparison
    evaluations: int
    iterations: int
    converged: bool
    path: tuple[tuple[float, float], ...]   # (gain thesis units, rms m) per evaluation

    @property
    def gain_thesis_units(self) -> float:
        return self.gain_rad_s_per_m / THESIS_SET_GAIN_V_PER_M

    @property
    def relative_residual(self) -> float:
        return self.rms_residual_m / self.rms_signal_m if self.rms_signal_m > 0 else math.nan

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["path"] = [list(p) for p in self.path]
        d["gain_thesis_units"] = self.gain_thesis_units
        d["relative_residual"] = self.relative_residual
        return d


def position_rms(real: Trace, nominal: Trace) -> float:
    """RMS of the LVDT position difference real - nominal (m)."""
    d = real["position_m"] - nominal["position_m"]
    return float(np.sqrt(np.mean(d * d)))


def fit_gain(real: Trace, mparams: MonitorParams | None = None,
             cparams: ControllerParams | None = None,
             start_thesis_units: float = THESIS_START_GAIN, xatol: float = 0.05,
             fatol: float = 1e-10, maxiter: int = 400) -> GainFit:
    """Fit the monitor's position P gain to `real` (a nominal high-fidelity trace) by
    Nelder-Mead from `start_thesis_units`, minimising the RMS position difference.

    Only the position gain is fitted; the speed PI gains stay the plant ECU's (as in the
    thesis: "the proportional and integral gains of the two PIs are equal to the high
    fidelity model"). The search runs in thesis units ((rad/s)/V = (rad/s)/m / 285.7),
    the variable fminsearch saw.
    """
    from scipy.optimize import minimize
    real.require(("position_m",) + NOMINAL_DRIVE, "the position-gain fit")
    mparams = mparams or MonitorParams.from_plant()
    path: list[tuple[float, float]] = []

    def cost(v: np.ndarray) -> float:
        g = float(v[0])
        if not math.isfinite(g) or g <= 0:
            r = 1.0   # far worse than any real residual (1 m RMS)
        else:
            nom = nominal_for(real, g * THESIS_SET_GAIN_V_PER_M, mparams, cparams)
            r = position_rms(real, nom)
            if not math.isfinite(r):
                r = 1.0
        path.append((g, r))
        return r

    res = minimize(cost, np.array([start_thesis_units]), method="Nelder-Mead",
                   options={"xatol": xatol, "fatol": fatol, "maxiter": maxiter})
    g = float(res.x[0])
    sig = real["position_m"]
    return GainFit(start_thesis_units=start_thesis_units,
                   gain_rad_s_per_m=g * THESIS_SET_GAIN_V_PER_M,
                   rms_residual_m=float(res.fun), rms_start_m=path[0][1],
                   rms_signal_m=float(np.sqrt(np.mean(sig * sig))),
                   plant_gain_rad_s_per_m=(cparams or ControllerParams()
                                           ).position_kp_rad_s_per_m,
                   evaluations=int(res.nfev), iterations=int(res.nit),
                   converged=bool(res.success), path=tuple(path))


def h1_profile() -> Profile:
    """The fit's maneuver: the thesis' fig. 6.2 sine (+-0.5 mm, 2 Hz, four periods)."""
    from bench.profiles.catalog import make_profile
    return make_profile("sine")


@lru_cache(maxsize=8)
def _fitted_cached(params_json: str, cparams_items: tuple[tuple[str, float], ...]
                   ) -> tuple[GainFit, Trace]:
    from bench.sim.harness import simulate
    params = PlantParams.from_json(params_json)
    cparams = ControllerParams(**dict(cparams_items))
    real = simulate(h1_profile(), params, cparams)
    fit = fit_gain(real.measured(), MonitorParams.from_plant(params), cparams)
    return fit, real


def fitted(params: PlantParams | None = None, cparams: ControllerParams | None = None
           ) -> tuple[GainFit, Trace]:
    """H1 for the nominal plant of `params`: (fit, the nominal high-fidelity trace).

    The nominal plant is `params` with its effects reset to nominal (no backlash, friction
    x1, no preload, no noise, no schedule): the monitor is fitted to the healthy actuator.
    Cached per parameter set within a process.
    """
    params = nominal_plant(params or PlantParams())
    cparams = cparams or ControllerParams(sample_period_s=params.sim.sync_period_s)
    return _fitted_cached(params.to_json(), tuple(sorted(asdict(cparams).items())))


def nominal_plant(params: PlantParams) -> PlantParams:
    """`params` with degradation, load, schedule and noise reset to nominal."""
    return params.with_dict({"effects.backlash_m": 0.0, "effects.friction_scale": 1.0,
                             "effects.preload_n": 0.0, "effects.viscous_scale": 1.0,
                             "schedule.kind": "none", "load.kind": "none",
                             "sensors.noise": False})
