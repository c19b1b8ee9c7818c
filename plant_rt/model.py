"""The plant's public model API: parameters -> compiled step -> measurements.

`Plant` is what the live CANopen node (`plant_rt.node`) and offline studies (the bench's
in-process harness) both hold. One call to `step(current_demand_a)` advances exactly one
SYNC period with that demand held by the drive, as the RPDO applied at a SYNC would be.

    plant = Plant(PlantParams())
    m = plant.measure()            # sensors at the current time
    plant.step(2.0)                # 1 ms with a 2 A current demand
    plant.truth()                  # simulation-only signals (never on the bus)
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ema_contract.states import Status
from plant_rt import kernel as K
from plant_rt import wear
from plant_rt.aero import GustGenerator
from plant_rt.contacts import contact_geometry, helix_rad, hertz_stiffness_ratio, worn_nut
from plant_rt.params import PlantParams

OVERTEMPERATURE_K = 428.0  # class H insulation, 155 degC


class Measurement(NamedTuple):
    """What the actuator's sensors give at one SYNC (SI units)."""
    current_a: float          # current sensor (eq. 5.2) + noise
    motor_speed_rad_s: float  # encoder speed (eq. 5.1) + noise
    motor_angle_rad: float    # encoder angle, quantised to counts
    position_m: float         # LVDT nut position (eq. 5.1) + noise
    temperature_k: float      # winding temperature (eq. 5.5)
    status: int
    load_n: float = 0.0       # load cell: F_ext averaged over the last period + noise


def param_vector(params: PlantParams) -> np.ndarray:
    """The kernel's parameter vector for `params` (derived quantities computed here)."""
    m, r, s, se, d, ld, sim = (params.motor, params.reducer, params.screw, params.sensors,
                               params.drive, params.load, params.sim)
    p = np.zeros(K.NP)
    p[K.P_R], p[K.P_L], p[K.P_KE], p[K.P_KT] = (m.resistance_ohm, m.inductance_h,
                                                m.ke_v_s_per_rad, m.kt_nm_per_a)
    p[K.P_IMAX], p[K.P_VDC] = m.current_max_a, m.supply_voltage_v
    p[K.P_RTH], p[K.P_TAMB] = m.thermal_resistance_k_per_w, m.ambient_temperature_k
    p[K.P_TAUW], p[K.P_TAUH] = m.thermal_time_constant_s, m.demod_time_constant_s
    p[K.P_ALPHA_R] = m.resistance_tempco_per_k
    tau = r.ratio
    p[K.P_TAU], p[K.P_ETA] = tau, r.efficiency
    p[K.P_JEQ] = equivalent_inertia(params)                                           # eq. 5.12
    p[K.P_CS] = static_friction(params)                                               # eq. 5.14
    p[K.P_STRA], p[K.P_STRV] = s.stribeck_amplitude, s.stribeck_velocity_rad_s
    p[K.P_CVISC] = viscous_friction(params)                                           # eq. 5.13
    alpha = helix_rad(s)                                     # at this lead (eq. 5.26)
    beta = math.radians(s.contact_angle_deg)
    p[K.P_Z], p[K.P_LEAD] = s.balls_active, s.lead_m
    p[K.P_G] = math.cos(alpha) * math.sin(beta)                                       # eq. 5.26
    p[K.P_LEVER_V] = math.sin(alpha) * math.sin(beta) * s.lever_m                     # eq. 5.10/15
    p[K.P_LEVER_R] = math.cos(alpha) * s.lever_m                                      # eq. 5.13
    p[K.P_FV], p[K.P_FS] = s.rolling_friction, s.nut_static_friction_n
    p[K.P_CN] = viscous_friction(params) / tau                                        # eq. 5.32
    p[K.P_MN], p[K.P_MB] = s.nut_mass_kg, s.ball_mass_kg
    p[K.P_KSTAR], p[K.P_MSLOPE] = contact_geometry(params)[:2]                        # eq. 5.21
    p[K.P_CDAMP] = s.contact_damping_n_s_per_m
    p[K.P_LZETA], p[K.P_LSIG] = se.lvdt_damping, se.lvdt_natural_rad_s
    p[K.P_LTAU] = se.lvdt_time_constant_s
    p[K.P_HREF] = s.hertz_reference_preload_n                  # 0: eq. 5.21's linear law
    p[K.P_PDRAG] = s.preload_drag_nm_per_n                     # 0: eq. 5.13's terms only
    p[K.P_INTERF] = 1.0 if s.preload_by_interference else 0.0   # 0: eq. 5.29's force
    p[K.P_EZETA], p[K.P_ESIG] = se.encoder_damping, se.encoder_natural_rad_s
    p[K.P_TAUC] = se.current_time_constant_s
    p[K.P_KPI], p[K.P_KII] = d.current_kp_v_per_a, current_ki(params)
    p[K.P_FPWM] = d.pwm_carrier_hz
    p[K.P_PWM_SW] = 1.0 if d.pwm_mode == "switching" else 0.0
    p[K.P_BALL_DYN] = 1.0 if sim.ball_model == "dynamic" else 0.0
    dt = sim.substep_s or (5e-6 if d.pwm_mode == "switching" else 20e-6)
    nsub = max(1, round(sim.sync_period_s / dt))
    p[K.P_DT] = sim.sync_period_s / nsub
    p[K.P_NSUB] = nsub
    p[K.P_NBALL] = ball_substeps(params, p[K.P_DT])
    p[K.P_LOAD_KIND] = K.LOAD_KINDS.index(ld.kind)
    p[K.P_AERO_GAIN] = ld.aero_gain_n_per_m
    p[K.P_LOAD_AMP], p[K.P_LOAD_T0] = ld.amplitude_n, ld.start_s
    p[K.P_LOAD_RATE], p[K.P_LOAD_FREQ] = ld.rate_n_per_s, ld.frequency_hz
    p[K.P_TRAVEL] = s.travel_limit_m
    w = params.wear
    p[K.P_WEAR_ON] = 1.0 if w.kind == "archard" else 0.0
    p[K.P_WEAR_GAIN] = wear.kernel_wear_gain(params)
    p[K.P_WEAR_AREA], p[K.P_WEAR_FRIC] = w.track_area_m2, w.friction_per_depth_per_m
    return p


def current_ki(params: PlantParams) -> float:
    """The drive's current-PI integral gain (V/(A s)): `drive.current_ki_v_per_as`, or,
    under `drive.current_pi_follows_winding`, kp R / L (its zero on the winding's pole)."""
    d, m = params.drive, params.motor
    if d.current_pi_follows_winding:
        return d.current_kp_v_per_a * m.resistance_ohm / m.inductance_h
    return d.current_ki_v_per_as


def equivalent_inertia(params: PlantParams) -> float:
    """I_eq, the inertia at the screw (kg m^2): (I_m + I_r) / tau^2 + I_s (eq. 5.12).
    The plant's screw shaft and the monitoring model's rigid screw (eq. 6.1) both use it."""
    m, r, s = params.motor, params.reducer, params.screw
    return (m.inertia_kg_m2 + r.inertia_kg_m2) / r.ratio**2 + s.screw_inertia_kg_m2


def static_friction(params: PlantParams) -> float:
    """C_s, the static friction torque at the screw (N m): (C_fm + C_fr) / tau + C_fs
    (eq. 5.14), the Coulomb level of the friction law eq. 5.13 (plant and monitor)."""
    m, r, s = params.motor, params.reducer, params.screw
    return (m.static_friction_nm + r.static_friction_nm) / r.ratio \
        + s.support_static_friction_nm


def viscous_friction(params: PlantParams) -> float:
    """c_sm + c_sr (N m s/rad), the viscous coefficient of eq. 5.13 (divided by tau there
    with the screw speed; plant and monitor)."""
    return params.motor.viscous_friction_nm_s + params.reducer.viscous_friction_nm_s


def ball_substeps(params: PlantParams, dt: float) -> int:
    """Ball micro-steps per sub-step: the explicit ball update of eq. 5.16 is stable for
    h < (2/w)(sqrt(1 + z^2) - z), w = sqrt(2k/M_b), z = c / sqrt(2 k M_b) (two contacts);
    the micro-step is held at 0.6 of that (a 1.67x margin) and at most 1 us."""
    s = params.screw
    kstar, mslope = contact_geometry(params)[:2]
    fpr = max(params.effects.preload_n, params.schedule.preload_start_n
              if params.schedule.kind != "none" else 0.0)
    k = kstar + mslope * fpr
    href = params.screw.hertz_reference_preload_n
    if href > 0.0:      # the Hertzian law's largest ratio: the tangent one at no load
        k = (kstar + mslope * href) * max(1.0, hertz_stiffness_ratio(0.0, fpr, href))
    w = math.sqrt(2 * k / s.ball_mass_kg)
    z = s.contact_damping_n_s_per_m / math.sqrt(2 * k * s.ball_mass_kg)
    h = min(1e-6, 0.6 * (2 / w) * (math.sqrt(1 + z * z) - z))
    return max(1, math.ceil(dt / h - 1e-9))


def separate_current_channel(params: PlantParams) -> float:
    """The kernel input U_ISEP: 1.0 when the logged current is a channel of its own
    (`sensors.current_in_loop` false: its errors stay out of the drive's loop), else 0.0."""
    return 0.0 if params.sensors.current_in_loop else 1.0


def sensor_vector(params: PlantParams) -> np.ndarray:
    """The kernel's sensor vector (gains, offsets, encoder resolution and speed window)."""
    se = params.sensors
    s = np.zeros(K.NS)
    s[K.S_IGAIN], s[K.S_IOFF] = se.current_gain, se.current_offset_a
    s[K.S_LGAIN], s[K.S_LOFF] = se.lvdt_gain, se.lvdt_offset_m
    s[K.S_EGAIN], s[K.S_RATIO] = se.encoder_gain, params.reducer.ratio
    s[K.S_COUNTS] = se.encoder_counts_per_rev
    s[K.S_WIN] = se.encoder_speed_window
    s[K.S_SYNC] = params.sim.sync_period_s
    s[K.S_QUANT] = 1.0 if se.encoder_quantised else 0.0
    return s


def schedule_at(params: PlantParams, t: float) -> tuple[float, float, float]:
    """(preload N, backlash m, friction scale) at time t (section 6.5 run-to-failure)."""
    e, sc = params.effects, params.schedule
    if sc.kind == "none":
        return e.preload_n, e.backlash_m, e.friction_scale
    frac = min(max(t / sc.duration_s, 0.0), 1.0)
    preload = sc.preload_start_n * max(0.0, 1.0 - frac / sc.preload_zero_frac)

    def grow(rate: float) -> float:
        return math.expm1(rate * frac) / math.expm1(rate)

    backlash = e.backlash_m + (sc.backlash_end_m - e.backlash_m) * grow(sc.backlash_growth)
    fscale = e.friction_scale + (sc.friction_end_scale - e.friction_scale) * grow(
        sc.friction_growth)
    return preload, backlash, fscale


def effects_at(params: PlantParams, t: float, volume_m3: float) -> tuple[float, float, float]:
    """(preload N, backlash m, friction scale) at time t with `volume_m3` worn: the
    schedule's (`schedule_at`), plus Archard wear under `wear.kind = archard` (the same
    mapping as the kernel's, `plant_rt.wear.effects_from_depth`); under
    `screw.preload_by_interference` the backlash first eats the preload's interference
    (`plant_rt.contacts.worn_nut`, before the wear, as in the kernel)."""
    preload, backlash, fscale = schedule_at(params, t)
    if params.screw.preload_by_interference:    # the clearance eats the interference first
        kstar, mslope, z, g = contact_geometry(params)
        preload, backlash = worn_nut(preload, backlash, kstar, mslope, z, g,
                                     params.screw.hertz_reference_preload_n)
    if params.wear.kind != "archard":
        return preload, backlash, fscale
    kstar, mslope, z, g = contact_geometry(params)
    loss, b_wear, f_wear = wear.effects_from_depth(
        volume_m3 / params.wear.track_area_m2, preload, kstar, mslope, z, g,
        params.wear.friction_per_depth_per_m)
    return preload - loss, backlash + b_wear, fscale * f_wear


def load_noise_seed(params: PlantParams) -> list[int]:
    """Seed of the load cell's noise stream (separate from the other sensors')."""
    return [int(params.sensors.noise_seed), 4]


class Plant:
    """The EMA plant of thesis chapter 5 behind a one-SYNC-period step."""

    def __init__(self, params: PlantParams | None = None) -> None:
        self.params = params or PlantParams()
        self._p = param_vector(self.params)
        self.x = np.zeros(K.NX)
        self.u = np.zeros(K.NU)
        self.out = np.zeros(K.NO)
        self.reset()

    # -- set-up --------------------------------------------------------------------
    def reset(self) -> None:
        """Back to rest at t = 0, nut at 0, preload seated, temperature at ambient."""
        self.x[:] = 0.0
        self.x[K.TEMP] = self.params.motor.ambient_temperature_k
        self.x[K.STS] = self.x[K.STN1] = self.x[K.STN2] = 1.0
        self.x[K.WEAR_V] = self.params.wear.initial_volume_m3
        self._gusts = GustGenerator(self.params)
        self._gust = self._gusts.next()
        self.out[:] = 0.0
        self._rng = np.random.default_rng(self.params.sensors.noise_seed)
        self._noise = np.zeros(3)
        self._rng_load = np.random.default_rng(load_noise_seed(self.params))
        self._noise_load = 0.0
        delay = round(self.params.effects.sensor_delay_s / self.params.sim.sync_period_s)
        self._hist: deque[np.ndarray] = deque(maxlen=max(delay, 1))
        self._ndelay = delay
        self._s = sensor_vector(self.params)
        self._m = np.zeros(K.NM)
        self._seat_preload()
        self._draw_noise()
        self._limited = False

    def _seat_preload(self) -> None:
        """Place the nuts where preload and contacts balance, so t = 0 is at rest."""
        preload, backlash, _ = effects_at(self.params, 0.0, float(self.x[K.WEAR_V]))
        if preload <= 0.0:
            return
        kstar, mslope, z, g = contact_geometry(self.params)
        k = kstar + mslope * preload
        href = self.params.screw.hertz_reference_preload_n
        if href > 0.0:      # the Hertzian law at no load (the kernel's first sub-step)
            k = (kstar + mslope * href) * hertz_stiffness_ratio(0.0, preload, href)
        g = self._p[K.P_G]
        # each nut: Z * (k/2) * g * dz = F_pr along x, dz = g dx  (series contacts)
        dz = preload / (z * 0.5 * k * g)             # compression along z
        dx = (dz + backlash / 2.0) / g
        self.x[K.X1], self.x[K.X2] = -dx, dx
        self.x[K.ZB1], self.x[K.ZB2] = -dx * g / 2.0, dx * g / 2.0

    def set_params(self, params: PlantParams) -> None:
        """Change parameters between steps (state kept)."""
        old = self.params
        self.params = params
        self._p = param_vector(params)
        self._s = sensor_vector(params)
        if params.load != old.load or params.sim.sync_period_s != old.sim.sync_period_s:
            self._gusts = GustGenerator(params)
            self._gust = self._gusts.next()

    @property
    def t(self) -> float:
        return float(self.x[K.T])

    @property
    def param_vector(self) -> np.ndarray:
        """The kernel's parameter vector (`plant_rt.kernel`'s P_* layout)."""
        return self._p

    @property
    def sensor_vector(self) -> np.ndarray:
        """The kernel's sensor vector for `kernel.measure` (S_* layout)."""
        return self._s

    # -- stepping ------------------------------------------------------------------
    def inputs(self, current_demand_a: float) -> np.ndarray:
        """The kernel input vector for the next period (schedules evaluated at its start)."""
        preload, backlash, fscale = schedule_at(self.params, self.t)
        u = self.u
        u[K.U_IDEM] = current_demand_a if math.isfinite(current_demand_a) else 0.0
        u[K.U_PRELOAD], u[K.U_BACKLASH], u[K.U_FSCALE] = preload, backlash, fscale
        u[K.U_VSCALE] = self.params.effects.viscous_scale
        u[K.U_INOISE] = self._noise[0]
        u[K.U_IGAIN] = self.params.sensors.current_gain
        u[K.U_IOFF] = self.params.sensors.current_offset_a
        u[K.U_ISEP] = separate_current_channel(self.params)
        u[K.U_GUST] = self._gust
        return u

    def step(self, current_demand_a: float) -> None:
        """Advance one SYNC period holding `current_demand_a` (A) in the drive."""
        if not np.isfinite(self.x).all():
            return  # FAULT: state lost; measure() reports it
        if self._ndelay:
            K.measure(self.x, self._s, self._noise, self._m)
            self._hist.append(self._m.copy())
        K.advance(self.x, self._p, self.inputs(current_demand_a), self.out)
        self._limited = bool(self.out[K.O_ILIM])
        self._draw_noise()
        self._gust = self._gusts.next()

    def _draw_noise(self) -> None:
        se = self.params.sensors
        if se.noise:
            z = self._rng.standard_normal(3)
            self._noise[:] = (z[0] * se.current_noise_a, z[1] * se.position_noise_m,
                              z[2] * se.speed_noise_rad_s)
            # the load cell's own stream: adding it left the other sensors' noise unchanged
            self._noise_load = float(self._rng_load.standard_normal()) * se.load_noise_n

    # -- outputs -------------------------------------------------------------------
    @property
    def nut_position_m(self) -> float:
        return float(0.5 * (self.x[K.X1] + self.x[K.X2]))

    def status(self) -> Status:
        st = Status.NONE
        if not np.isfinite(self.x).all():
            return Status.FAULT
        if self._limited:
            st |= Status.OVERCURRENT
        if abs(self.nut_position_m) > self.params.screw.travel_limit_m:
            st |= Status.END_OF_STROKE
        if self.x[K.TEMP] > OVERTEMPERATURE_K:
            st |= Status.OVERTEMPERATURE
        return st

    def measure(self) -> Measurement:
        """Sensor readings at the current time (what the TPDOs carry); no side effects."""
        m = self._m
        K.measure(self.x, self._s, self._noise, m)
        cur, temp = m[K.M_CUR], m[K.M_TEMP]
        if self._ndelay and self._hist:  # LVDT and encoder samples sensor_delay_s old
            m = self._hist[0]   # (the first sample repeats until the history is full)
        return Measurement(float(cur), float(m[K.M_SPEED]), float(m[K.M_ANGLE]),
                           float(m[K.M_POS]), float(temp), int(self.status()),
                           float(self.out[K.O_FEXT]) + self._noise_load)

    def truth(self) -> dict[str, float]:
        """Simulation-only signals at the current time / over the last period."""
        x, o = self.x, self.out
        preload, backlash, fscale = effects_at(self.params, self.t, float(x[K.WEAR_V]))
        return {
            "true_position_m": self.nut_position_m,
            "true_current_a": float(x[K.I]),
            "true_motor_speed_rad_s": float(x[K.OM] / self.params.reducer.ratio),
            "motor_torque_nm": float(x[K.TQ]),
            "friction_torque_nm": float(o[K.O_FRIC_T]),
            "friction_force_n": float(o[K.O_FRIC_F]),
            "reaction_torque_nm": float(o[K.O_REACT_T]),
            "temperature_k": float(x[K.TEMP]),
            "ext_force_n": float(o[K.O_FEXT]),
            "backlash_m": backlash,
            "friction_scale": fscale,
            "preload_n": preload,
            "voltage_v": float(o[K.O_VOLT]),
            "wear_volume_m3": float(x[K.WEAR_V]),
        }

    def state(self) -> dict[str, float]:
        """The whole state vector by name."""
        return dict(zip(K.STATE_NAMES, map(float, self.x), strict=True))


def warm_up(params: PlantParams | None = None,
            factory: Callable[[PlantParams], Plant] | None = None) -> None:
    """Load the compiled plant step and sensors (numba's disk cache, or a compile of
    seconds on a cold one) on a throwaway plant (`factory(params)`, a `Plant` by
    default), so that no node pays for it at its first SYNC: a node silent that long
    misses its heartbeat and is declared lost."""
    params = params or PlantParams()
    p = (factory or Plant)(params)
    p.step(0.0)
    p.measure()
