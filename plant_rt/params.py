"""Plant parameter sets as typed, documented data with units (thesis tables 5.1-5.4).

Every leaf field carries its unit in its name and, in its metadata, a unit string, a
valid range, a source and a one-line description. `PlantParams` groups them; it is
frozen, validates itself on construction (NaN, out-of-range, unknown names raise
`ParameterError` naming the parameter), round-trips through JSON and exposes a flat
name space (``motor.resistance_ohm`` or just ``resistance_ohm``) used by ``--set``,
``--list-params`` and the plant's SDO objects.

Values not given in the thesis are marked ``source="chosen"`` (explained in docs/model.md).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import Counter
from dataclasses import dataclass, field, fields, replace
from typing import Any, ClassVar

from plant_rt.paramvalues import SEED_MAX, json_object, same_value


class ParameterError(ValueError):
    """A plant parameter is unknown or has an invalid value."""


def P(default: Any, unit: str, lo: float | None, hi: float | None, doc: str,
      source: str = "", choices: tuple[str, ...] | None = None) -> Any:
    """A parameter field with its unit, range [lo, hi], description and source."""
    return field(default=default, metadata={
        "unit": unit, "min": lo, "max": hi, "doc": doc, "source": source,
        "choices": choices})


class _Validated:
    """Frozen parameter groups check every field against its metadata on construction."""
    _group: ClassVar[str] = ""

    def __post_init__(self) -> None:
        _validate_group(self, self._group)


@dataclass(frozen=True)
class MotorParams(_Validated):
    """Single-phase equivalent BLDC motor (eq. 5.3-5.6, table 5.2)."""
    _group: ClassVar[str] = "motor"
    resistance_ohm: float = P(0.4, "ohm", 1e-4, 100.0, "winding resistance R", "table 5.2")
    inductance_h: float = P(6e-3, "H", 1e-6, 1.0, "winding inductance L", "table 5.2")
    inertia_kg_m2: float = P(4e-3, "kg m^2", 1e-7, 10.0, "rotor inertia I_m", "table 5.2")
    ke_v_s_per_rad: float = P(1.15, "V/(rad/s)", 1e-3, 100.0, "back-EMF constant k_e", "table 5.2")
    kt_nm_per_a: float = P(1.5, "N m/A", 1e-3, 100.0, "torque constant k_t", "table 5.2")
    current_max_a: float = P(25.0, "A", 0.1, 1000.0, "current limit i_max", "table 5.2")
    supply_voltage_v: float = P(400.0, "V", 1.0, 2000.0, "DC bus voltage V_a", "table 5.2")
    thermal_resistance_k_per_w: float = P(2.3, "K/W", 1e-3, 100.0,
                                          "winding-to-ambient thermal resistance R_th",
                                          "table 5.2 (printed as W/K)")
    ambient_temperature_k: float = P(233.0, "K", 150.0, 400.0, "reference temperature T_rif",
                                     "table 5.2")
    thermal_time_constant_s: float = P(13.0, "s", 1e-3, 1e5, "thermal time constant tau_w",
                                       "table 5.2")
    demod_time_constant_s: float = P(1.99e-4, "s", 1e-7, 1.0,
                                     "torque demodulation filter time constant tau_h",
                                     "table 5.2")
    resistance_tempco_per_k: float = P(0.0, "1/K", 0.0, 0.01,
                                       "winding resistance temperature coefficient (0: the "
                                       "thesis' uncoupled thermal model; copper 0.00393)",
                                       "chosen")
    static_friction_nm: float = P(0.013, "N m", 0.0, 10.0, "motor static friction torque C_fm",
                                  "table 5.4")
    viscous_friction_nm_s: float = P(5.8e-8, "N m s/rad", 0.0, 1.0,
                                     "motor viscous friction coefficient c_sm", "table 5.4")


@dataclass(frozen=True)
class ReducerParams(_Validated):
    """Ideal reducer with efficiency (eq. 5.7-5.8, table 5.3)."""
    _group: ClassVar[str] = "reducer"
    efficiency: float = P(0.95, "-", 0.1, 1.0, "reducer efficiency eta", "table 5.3")
    ratio: float = P(0.25, "-", 1e-3, 10.0, "transmission ratio tau (screw speed / motor speed)",
                     "table 5.3")
    inertia_kg_m2: float = P(3e-5, "kg m^2", 0.0, 10.0, "reducer inertia I_r", "table 5.3")
    static_friction_nm: float = P(0.0173, "N m", 0.0, 10.0, "reducer static friction torque C_fr",
                                  "table 5.4")
    viscous_friction_nm_s: float = P(2.2e-8, "N m s/rad", 0.0, 1.0,
                                     "reducer viscous friction coefficient c_sr", "table 5.4")


@dataclass(frozen=True)
class ScrewParams(_Validated):
    """Ball screw: shaft, balls, double nut (eq. 5.9-5.32, table 5.4)."""
    _group: ClassVar[str] = "screw"
    balls_active: int = P(21, "-", 1, 1000, "active balls Z per nut", "table 5.4")
    screw_inertia_kg_m2: float = P(8e-5, "kg m^2", 1e-8, 10.0, "screw inertia I_s", "table 5.4")
    lead_m: float = P(5e-3, "m", 1e-4, 0.1, "screw lead (pitch) p", "table 5.4")
    ball_radius_m: float = P(2e-3, "m", 1e-4, 0.05, "ball radius r_b", "table 5.4")
    nominal_radius_m: float = P(15e-3, "m", 1e-3, 0.5, "screw nominal radius r_m", "table 5.4")
    helix_angle_deg: float = P(3.04, "deg", 0.1, 45.0, "helix angle alpha", "table 5.4")
    contact_angle_deg: float = P(45.0, "deg", 1.0, 89.0, "contact angle beta", "section 5.6")
    nut_mass_kg: float = P(0.54, "kg", 1e-3, 100.0, "double nut mass M_n", "table 5.4")
    ball_mass_kg: float = P(2.7e-4, "kg", 1e-6, 1.0, "ball mass M_b", "table 5.4")
    rolling_friction: float = P(1e-3, "-", 0.0, 0.1, "rolling friction coefficient f_v",
                                "table 5.4")
    support_static_friction_nm: float = P(0.055, "N m", 0.0, 10.0,
                                          "support static friction torque C_fs", "table 5.4")
    nut_static_friction_n: float = P(221.4, "N", 0.0, 1e5,
                                     "nut static friction force F_s (eq. 5.31): C_s 2 pi/p, so "
                                     "that nut and screw friction are equal, as eq. 6.1 assumes",
                                     "chosen")
    stribeck_amplitude: float = P(0.1, "-", 0.0, 5.0,
                                  "Stribeck overshoot of static over Coulomb friction (eq. 5.13)",
                                  "eq. 5.13")
    stribeck_velocity_rad_s: float = P(1.0, "rad/s", 1e-3, 1e3,
                                       "Stribeck velocity of the screw (eq. 5.13: e^-|w|)",
                                       "eq. 5.13")
    contact_stiffness_n_per_m: float = P(1e8, "N/m", 1e5, 1e11,
                                         "contact stiffness without preload k* (eq. 5.21)",
                                         "section 5.6.2")
    stiffness_preload_slope_per_m: float = P(820.5, "1/m", 0.0, 1e7,
                                             "stiffness-preload slope m (eq. 5.21)",
                                             "section 5.6.2")
    contact_damping_n_s_per_m: float = P(150.0, "N s/m", 5.0, 1e5,
                                         "contact damping c per contact (eq. 5.17-5.18): "
                                         "damping ratio 0.65 for one ball on its two contacts",
                                         "chosen")
    reaction_lever_m: float = P(float("nan"), "m", 0.0, 0.5,
                                "lever of the reaction torque C_V; NaN: r_m - r_b cos(beta) "
                                "(eq. 5.10); r_m makes the transmission work-consistent",
                                "eq. 5.10")
    travel_limit_m: float = P(0.05, "m", 1e-3, 10.0, "end-of-stroke limit |x_n| (flag only)",
                              "chosen (stroke not stated)")
    stiffness_reading: str = P("contact", "-", None, None,
                               "how k* (contact_stiffness_n_per_m) is read: contact: the "
                               "stiffness of each ball contact (eq. 5.21 as implemented so "
                               "far); axial: the screw's axial stiffness without preload, "
                               "shared by circuits x Z balls, two contacts in series, along "
                               "the contact normal (docs/model.md, 'Stiffness')",
                               "section 5.6.2", choices=("contact", "axial"))
    circuits: int = P(6, "-", 1, 100,
                      "ball circuits of the double nut (both nuts; the axial reading "
                      "shares k* over circuits x Z balls, eq. 5.11)", "table 5.4")
    dynamic_load_rating_n: float = P(
        22000.0, "N", 100.0, 1e6,
        "basic dynamic axial load rating C_a of the nut carrying the load (one nut of the "
        "double nut): 10^6 revolutions at 90 % reliability (ISO 3408-5, Lundberg-Palmgren); "
        "used by the usage monitoring (bench/usage), not by the physics",
        "catalogue class of the thesis size (d0 = 2 r_m = 30 mm, nearest ISO size 32 x 5 mm, "
        "3.5 mm balls, 4 loaded turns): Bosch Rexroth precision ball screw assemblies "
        "R310EN 3301, FEM-E-S / FDM-E-S 32x5R-3.5-4, about 22 kN; the catalogue page was not "
        "at hand to check here (docs/usage.md)")
    hertz_reference_preload_n: float = P(
        0.0, "N", 0.0, 50000.0,
        "Hertzian preloaded double nut: 0 = eq. 5.21's linear law k* + m F_pr (the "
        "default); > 0 = the balls are Hertzian contacts (F ~ delta^1.5) and k* + m F_ref "
        "is the contact stiffness at this preload F_ref (the nut as built, where k* is "
        "measured or calibrated); at preload F_pr and axial load F the contacts' stiffness "
        "is scaled by the double nut's secant stiffness at (F, F_pr) over that at (F, F_ref): "
        "(F_pr / F_ref)^(1/3) at small loads, the unloaded half's lift-off beyond "
        "2^1.5 F_pr (plant_rt.contacts.hertz_stiffness_ratio; docs/model.md)",
        "Hertz contact (thesis section 2: the loaded nut's elliptical contacts 'according "
        "to Hertz contacts theory'; K. L. Johnson, Contact Mechanics, 1985, ch. 4); "
        "a preloaded double nut's catalogue (e.g. THK: axial stiffness ~ F_a0^(1/3))")
    preload_drag_nm_per_n: float = P(
        0.0, "N m/N", 0.0, 1e-2,
        "a preloaded nut's no-load drag torque at the screw per N of preload, T_p = this x "
        "F_pr, added to the screw's Coulomb level C_s (eq. 5.14) and scaled with it by the "
        "friction scale; 0 (default) = none beyond the rolling terms of eq. 5.13 and 5.31 "
        "(f_v on the contact forces, which carry the preload)",
        "0: thesis; > 0: a catalogue's preload drag torque (e.g. THK's 'preload dynamic "
        "torque' T_p = 0.05 (tan lambda)^-0.5 F_pr p / 2 pi)")
    preload_by_interference: bool = P(
        False, "-", None, None,
        "false (default): eq. 5.29, the preload a force +-F_pr per half that takes up any "
        "backlash; true: an interference (a spacer between the halves) that "
        "effects.backlash_m, a wear clearance, eats first: the preload falls to what the "
        "rest holds (eq. 5.21 or the Hertzian law), only the clearance beyond it is lost "
        "motion (plant_rt.contacts.worn_nut; docs/gap.md, 'The verdict in words')",
        "thesis section 2.1 (fig. 2.4(b): a double nut with a thickness between the nuts; "
        "the preload reduces the axial play), eq. 2.19 (preload loss = nut stiffness x "
        "the deformation wear removes) and section 2.3 (backlash appears when the preload "
        "is null); a spacer-preloaded nut's datasheet")
    helix_reference_lead_m: float = P(
        0.0, "m", 0.0, 0.1, "0 (default): alpha as given at any lead (the thesis' model); "
        "> 0: the lead at which helix_angle_deg holds, at another lead the helix follows "
        "it, tan alpha ~ p at the same r_m, and so does the torque per axial force "
        "(plant_rt.contacts.helix_rad)", "0: thesis (table 5.4's 3.04 deg is atan(p / 2 pi "
        "r_m) at its 5 mm); > 0: a screw's geometry (docs/gap.md, 'Calibration')")

    @property
    def lever_m(self) -> float:
        if math.isnan(self.reaction_lever_m):
            return self.nominal_radius_m - self.ball_radius_m * math.cos(
                math.radians(self.contact_angle_deg))
        return self.reaction_lever_m


@dataclass(frozen=True)
class SensorParams(_Validated):
    """Sensors (eq. 5.1-5.2, table 5.1) and their white noise."""
    _group: ClassVar[str] = "sensors"
    lvdt_damping: float = P(0.8, "-", 0.05, 5.0, "LVDT damping zeta_pos", "table 5.1")
    lvdt_natural_rad_s: float = P(1256.0, "rad/s", 1.0, 1e6, "LVDT eigenfrequency sigma_pos",
                                  "table 5.1")
    encoder_damping: float = P(0.8, "-", 0.05, 5.0, "encoder damping zeta_v", "table 5.1")
    encoder_natural_rad_s: float = P(3768.0, "rad/s", 1.0, 1e6,
                                     "encoder eigenfrequency sigma_v", "table 5.1")
    current_time_constant_s: float = P(7.96e-5, "s", 1e-8, 1.0,
                                       "current sensor time constant tau_c", "table 5.1")
    lvdt_gain: float = P(1.0, "-", 0.5, 2.0, "LVDT gain error (1 = exact)", "chosen")
    lvdt_offset_m: float = P(0.0, "m", -0.01, 0.01, "LVDT offset", "chosen")
    encoder_gain: float = P(1.0, "-", 0.5, 2.0, "encoder speed gain error (1 = exact)", "chosen")
    current_gain: float = P(1.0, "-", 0.5, 2.0, "current sensor gain error (1 = exact)", "chosen")
    current_offset_a: float = P(0.0, "A", -5.0, 5.0, "current sensor offset", "chosen")
    encoder_counts_per_rev: int = P(16384, "counts/rev", 16, 2**24,
                                    "encoder resolution on the motor shaft", "chosen")
    noise: bool = P(False, "-", None, None, "white sensor noise on/off", "section 5.1")
    noise_seed: int = P(1, "-", 0, SEED_MAX, "seed of the sensor noise generator", "chosen")
    current_noise_a: float = P(0.1, "A", 0.0, 10.0, "current noise std per SYNC sample",
                               "chosen")
    position_noise_m: float = P(2e-6, "m", 0.0, 1e-3, "LVDT noise std per SYNC sample",
                                "chosen")
    speed_noise_rad_s: float = P(0.2, "rad/s", 0.0, 100.0, "encoder speed noise std",
                                 "chosen")
    load_noise_n: float = P(2.0, "N", 0.0, 1000.0,
                            "load cell (strain-gauge bridge, section 4.4) noise std per "
                            "SYNC sample; the cell reads F_ext averaged over the period",
                            "chosen")
    encoder_speed_window: int = P(
        0, "SYNC periods", 0, 16,
        "how the drive computes the encoder speed: 0 = the second-order sensor filter of "
        "eq. 5.1 on the shaft speed; N >= 1 = the quantised count difference over the "
        "last N SYNC periods / (N T) (a drive's datasheet fact, e.g. 'speed from the "
        "counts over 4 SYNC periods')", "table 5.1 (0); a drive's datasheet (N >= 1)")
    lvdt_time_constant_s: float = P(
        0.0, "s", 0.0, 0.1,
        "LVDT signal conditioning: 0 = the second-order sensor filter of eq. 5.1 "
        "(lvdt_natural_rad_s, lvdt_damping); > 0 = a first-order demodulator lag of this "
        "time constant instead (a conditioner's datasheet fact, e.g. 'first-order 1 ms')",
        "table 5.1 (0); a conditioner's datasheet (> 0)")
    encoder_quantised: bool = P(
        True, "-", None, None,
        "the encoder angle in whole counts (true, the sensor), or (false) the quantiser's "
        "expectation over its phase, angle - half a count: the continuous encoder a fit "
        "simulates, so that its cost is a smooth function of the parameters", "chosen")
    current_in_loop: bool = P(True, "-", None, None, "the logged current is the drive's "
                              "feedback sensor (true: its gain, offset and noise enter the "
                              "current loop) or a channel of its own (false: in the log alone)",
                              "section 5.3 (true); an actuator's datasheet (false)")


@dataclass(frozen=True)
class DriveParams(_Validated):
    """The drive: current PI at the PWM rate, PWM and inverter (section 5.3)."""
    _group: ClassVar[str] = "drive"
    current_kp_v_per_a: float = P(20.0, "V/A", 0.0, 1e4,
                                  "current loop proportional gain: 800 Hz closed-loop "
                                  "bandwidth (section 5.2.2)",
                                  "tuned here (thesis gains not given)")
    current_ki_v_per_as: float = P(1333.3, "V/(A s)", 0.0, 1e7,
                                   "current loop integral gain: zero on the winding pole R/L",
                                   "tuned here (thesis gains not given)")
    pwm_carrier_hz: float = P(10000.0, "Hz", 1000.0, 100000.0,
                              "triangular carrier frequency", "section 5.3")
    pwm_mode: str = P("switching", "-", None, None,
                      "switching: 10 kHz triangular carrier and inverter; averaged: ideal "
                      "averaged voltage (infinite carrier)", "section 5.3",
                      choices=("switching", "averaged"))
    current_pi_follows_winding: bool = P(False, "-", None, None,
                                         "true: the integral gain is kp R / L from the "
                                         "model's winding (zero on its actual pole, as a "
                                         "drive that identifies its motor at power-up); "
                                         "false: the gains as given",
                                         "chosen (the thesis' drive: fixed gains); a "
                                         "drive's datasheet")


@dataclass(frozen=True)
class EffectParams(_Validated):
    """Degradation and effect parameters held constant during a run (section 5.7.4)."""
    _group: ClassVar[str] = "effects"
    backlash_m: float = P(0.0, "m", 0.0, 1e-3,
                          "backlash b_max along the contact normal (eq. 5.19-5.24); axial "
                          "lost motion b/(cos alpha sin beta) = 1.416 b", "5.7.4")
    friction_scale: float = P(1.0, "-", 0.0, 20.0,
                              "scale of static/Coulomb friction torques and forces (1 = "
                              "nominal, 4 = 100 % degradation)", "5.7.4")
    viscous_scale: float = P(1.0, "-", 0.0, 1e6, "scale of viscous friction coefficients",
                             "chosen")
    preload_n: float = P(0.0, "N", 0.0, 50000.0, "double-nut preload F_pr (eq. 5.21, 5.29)",
                         "5.7.3")
    sensor_delay_s: float = P(0.0, "s", 0.0, 0.01,
                              "pure delay on the LVDT and encoder samples (whole SYNC periods)",
                              "chosen")


@dataclass(frozen=True)
class LoadParams(_Validated):
    """External axial force on the nut, F_ext (eq. 5.29-5.30)."""
    _group: ClassVar[str] = "load"
    kind: str = P("none", "-", None, None,
                  "none, step, ramp, sine, or aero (hinge moment: aero_gain_n_per_m x nut "
                  "position plus seeded gusts)", "5.7.2; aero: chosen (docs/model.md)",
                  choices=("none", "step", "ramp", "sine", "aero"))
    amplitude_n: float = P(0.0, "N", -1e5, 1e5, "final (step/ramp) or peak (sine) force", "5.7.2")
    start_s: float = P(0.0, "s", 0.0, 1e6, "time the force starts", "5.7.2")
    rate_n_per_s: float = P(1.5e6, "N/s", 1.0, 1e9, "ramp slope (step: 0.01 s rise)", "5.7.2")
    frequency_hz: float = P(2.0, "Hz", 0.0, 1e3, "sine frequency", "5.7.2")
    aero_gain_n_per_m: float = P(3e5, "N/m", 0.0, 1e8,
                                 "aero: axial force per metre of nut travel from neutral (the "
                                 "hinge moment grows with deflection); 15 kN, the thesis' load "
                                 "test force, at the 50 mm stroke limit",
                                 "chosen from 5.7.3 (docs/model.md)")
    gust_std_n: float = P(1000.0, "N", 0.0, 1e5,
                          "aero: standard deviation of the gust force (first-order coloured "
                          "noise, held per SYNC period)", "chosen (docs/model.md)")
    gust_time_constant_s: float = P(0.5, "s", 1e-3, 100.0,
                                    "aero: correlation time of the gust force (Dryden-type "
                                    "first-order filter)", "chosen (docs/model.md)")
    gust_seed: int = P(7, "-", 0, SEED_MAX, "aero: seed of the gust generator", "chosen")


@dataclass(frozen=True)
class ScheduleParams(_Validated):
    """Time-varying degradation for run-to-failure runs (section 6.5).

    preload(t) falls linearly from `preload_start_n` to 0 at `preload_zero_frac` of the
    run; backlash(t) and friction_scale(t) grow as (e^(g t/T) - 1)/(e^g - 1) to their
    end values. The growth rates reproduce the two states the thesis quotes at 118 s of
    120 s (85 um, x3.9): g_backlash = 10, g_friction = 2.
    """
    _group: ClassVar[str] = "schedule"
    kind: str = P("none", "-", None, None, "none or rul", "6.5", choices=("none", "rul"))
    duration_s: float = P(120.0, "s", 0.1, 1e6, "run length T", "6.5")
    preload_start_n: float = P(2000.0, "N", 0.0, 50000.0, "preload at t=0", "6.5")
    preload_zero_frac: float = P(0.5, "-", 0.01, 1.0, "fraction of T where preload reaches 0",
                                 "6.5 (first part)")
    backlash_end_m: float = P(100e-6, "m", 0.0, 1e-3, "backlash at T", "6.5")
    friction_end_scale: float = P(4.0, "-", 1.0, 20.0, "friction scale at T", "6.5")
    backlash_growth: float = P(10.0, "-", 0.01, 50.0, "exponential growth rate of backlash",
                               "fitted to 85 um at 118 s")
    friction_growth: float = P(2.0, "-", 0.01, 50.0, "exponential growth rate of friction",
                               "fitted to x3.9 at 118 s")


@dataclass(frozen=True)
class WearParams(_Validated):
    """Use-driven (Archard) wear of the ball tracks (`plant_rt.wear`, docs/model.md).

    Worn volume rate = k F_N v_roll / H (Archard 1953), k drawn per actuator from a
    log-normal distribution by `seed`; the volume maps to preload loss, backlash and a
    friction scale. The HUMS never reads this group: the coefficient is the hidden truth.
    """
    _group: ClassVar[str] = "wear"
    kind: str = P("schedule", "-", None, None,
                  "schedule: degradation from effects.* and the time-based schedule.* "
                  "(section 6.5); archard: effects.* are the new actuator and wear from "
                  "use adds to them", "6.5; Archard 1953", choices=("schedule", "archard"))
    coefficient_median: float = P(1e-8, "-", 0.0, 1e-2,
                                  "median dimensionless Archard coefficient k of the "
                                  "population (lubricated steel, rolling with micro-slip)",
                                  "chosen (docs/model.md)")
    coefficient_log_std: float = P(0.5, "-", 0.0, 3.0,
                                   "standard deviation of ln k across actuators (0: every "
                                   "actuator has the median)", "chosen (docs/model.md)")
    seed: int = P(1, "-", 0, SEED_MAX,
                  "actuator seed: draws this actuator's k from the distribution", "chosen")
    acceleration: float = P(1.0, "-", 1e-3, 1e9,
                            "time compression of wear (multiplies k): 1 = real use",
                            "chosen")
    hardness_pa: float = P(7.4e9, "Pa", 1e8, 1e11,
                           "raceway hardness H (bearing steel, HV 750 ~ 60 HRC)",
                           "chosen (ISO 3408-5 raceways 58-62 HRC)")
    track_area_m2: float = P(2.0e-4, "m^2", 1e-7, 1.0,
                             "area the worn volume is spread over: 4 contacts per ball "
                             "chain pair x Z balls x 2 r_b track length x 0.6 mm width",
                             "chosen (docs/model.md)")
    friction_per_depth_per_m: float = P(1.2e5, "1/m", 0.0, 1e9,
                                        "friction scale growth per metre of wear depth: x4 "
                                        "at 25 um (100 um of backlash, section 6.5)",
                                        "6.5 end state (docs/model.md)")
    initial_volume_m3: float = P(0.0, "m^3", 0.0, 1e-3,
                                 "worn volume at the start of the run (a campaign carries "
                                 "it from day to day)", "chosen")


@dataclass(frozen=True)
class SimParams(_Validated):
    """Integration settings of the compiled fixed-step core."""
    _group: ClassVar[str] = "sim"
    sync_period_s: float = P(1e-3, "s", 1e-4, 0.1, "SYNC (ECU sample) period",
                             "chosen (docs/model.md)")
    substep_s: float = P(0.0, "s", 0.0, 1e-3, "integration step; 0 picks 5 us (switching PWM) "
                         "or 20 us (averaged)", "chosen")
    ball_model: str = P("dynamic", "-", None, None,
                        "dynamic: ball masses of eq. 5.16 (sub-cycled at 0.5 us); "
                        "quasistatic: massless balls, the two contacts in series",
                        "eq. 5.16", choices=("dynamic", "quasistatic"))


GROUPS: dict[str, type] = {
    "motor": MotorParams, "reducer": ReducerParams, "screw": ScrewParams,
    "sensors": SensorParams, "drive": DriveParams, "effects": EffectParams,
    "load": LoadParams, "schedule": ScheduleParams, "sim": SimParams, "wear": WearParams,
}


@dataclass(frozen=True)
class ParamInfo:
    """Description of one settable parameter (for --list-params, SDO and docs)."""
    name: str          # dotted name, e.g. "motor.resistance_ohm"
    group: str
    leaf: str
    type: type
    default: Any
    unit: str
    min: float | None
    max: float | None
    doc: str
    source: str
    choices: tuple[str, ...] | None


def _infos() -> list[ParamInfo]:
    out = []
    for g, cls in GROUPS.items():
        for f in fields(cls):
            m = f.metadata
            typ = {"float": float, "int": int, "bool": bool, "str": str}[f.type] \
                if isinstance(f.type, str) else f.type
            out.append(ParamInfo(f"{g}.{f.name}", g, f.name, typ, f.default, m["unit"],
                                 m["min"], m["max"], m["doc"], m["source"], m["choices"]))
    return out


PARAMS: list[ParamInfo] = _infos()
_BY_NAME: dict[str, ParamInfo] = {p.name: p for p in PARAMS}
# Leaf aliases only where unique ("backlash_m" -> "effects.backlash_m").
_leaf_counts = Counter(p.leaf for p in PARAMS)
_ALIASES: dict[str, str] = {p.leaf: p.name for p in PARAMS if _leaf_counts[p.leaf] == 1}


def resolve(name: str) -> ParamInfo:
    """The parameter called `name` (dotted, or a unique leaf name); ParameterError if none."""
    key = _ALIASES.get(name, name)
    try:
        return _BY_NAME[key]
    except KeyError:
        close = [p.name for p in PARAMS if name.split(".")[-1] in p.name][:5]
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ParameterError(f"unknown parameter {name!r}{hint}") from None


def check_value(info: ParamInfo, value: Any) -> Any:
    """`value` coerced to the parameter's type and checked against its range."""
    if info.type is bool:
        return _check_bool(info.name, value)
    if info.type is str:
        if not isinstance(value, str) or (info.choices and value not in info.choices):
            raise ParameterError(f"{info.name}: expected one of {', '.join(info.choices or ())}, "
                                 f"got {value!r}")
        return value
    return _check_number(info, value)


def _check_bool(name: str, value: Any) -> bool:
    """`check_value` of a boolean: on/off words, or 0/1."""
    if isinstance(value, str):
        low = value.strip().lower()
        if low in ("1", "true", "on", "yes"):
            return True
        if low in ("0", "false", "off", "no"):
            return False
        raise ParameterError(f"{name}: expected on/off, got {value!r}")
    if isinstance(value, (bool, int)) and value in (0, 1):
        return bool(value)
    raise ParameterError(f"{name}: expected a boolean, got {value!r}")


def _check_number(info: ParamInfo, value: Any) -> float | int:
    """`check_value` of an int or float parameter: finite (NaN only for the lever that
    it selects) and within the range."""
    name = info.name
    try:
        num: float | int = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}: expected a number in {info.unit}, got {value!r}") from None
    if info.type is int:
        if not math.isfinite(num) or num != int(num):
            raise ParameterError(f"{name}: expected an integer, got {value!r}")
        num = int(num)
    if math.isnan(num):
        if info.name == "screw.reaction_lever_m":
            return num  # NaN selects the eq. 5.10 lever
        raise ParameterError(f"{name}: NaN is not a valid value")
    if not math.isfinite(num):
        raise ParameterError(f"{name}: {value!r} is not finite")
    if info.min is not None and num < info.min:
        raise ParameterError(f"{name} = {num:g} {info.unit} is below its minimum "
                             f"{info.min:g} {info.unit}")
    if info.max is not None and num > info.max:
        raise ParameterError(f"{name} = {num:g} {info.unit} is above its maximum "
                             f"{info.max:g} {info.unit}")
    return num


def _validate_group(obj: Any, group: str) -> None:
    for f in fields(obj):
        info = _BY_NAME[f"{group}.{f.name}"]
        v = check_value(info, getattr(obj, f.name))
        object.__setattr__(obj, f.name, v)


@dataclass(frozen=True)
class PlantParams:
    """The whole plant: one frozen, validated parameter set."""
    motor: MotorParams = field(default_factory=MotorParams)
    reducer: ReducerParams = field(default_factory=ReducerParams)
    screw: ScrewParams = field(default_factory=ScrewParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    drive: DriveParams = field(default_factory=DriveParams)
    effects: EffectParams = field(default_factory=EffectParams)
    load: LoadParams = field(default_factory=LoadParams)
    schedule: ScheduleParams = field(default_factory=ScheduleParams)
    sim: SimParams = field(default_factory=SimParams)
    wear: WearParams = field(default_factory=WearParams)

    # -- flat access ---------------------------------------------------------------
    def get(self, name: str) -> Any:
        info = resolve(name)
        return getattr(getattr(self, info.group), info.leaf)

    def with_values(self, **values: Any) -> PlantParams:
        """A copy with parameters set by name (dotted, or unique leaf with ``__`` for dots)."""
        return self.with_dict({k.replace("__", "."): v for k, v in values.items()})

    def with_dict(self, values: dict[str, Any]) -> PlantParams:
        groups: dict[str, dict[str, Any]] = {}
        for name, v in values.items():
            info = resolve(name)
            groups.setdefault(info.group, {})[info.leaf] = check_value(info, v)
        new = self
        for g, kv in groups.items():
            new = replace(new, **{g: replace(getattr(new, g), **kv)})
        return new

    def with_assignments(self, assignments: list[str]) -> PlantParams:
        """Apply ``NAME=VALUE`` strings (the CLI's ``--set``)."""
        values: dict[str, Any] = {}
        for a in assignments:
            if "=" not in a:
                raise ParameterError(f"--set expects NAME=VALUE, got {a!r}")
            k, v = a.split("=", 1)
            values[k.strip()] = v.strip()
        return self.with_dict(values)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        return dataclasses.asdict(self)

    def flat(self) -> dict[str, Any]:
        return {p.name: self.get(p.name) for p in PARAMS}

    def to_json(self, indent: int = 2) -> str:
        def enc(x: Any) -> Any:
            return None if isinstance(x, float) and math.isnan(x) else x
        return json.dumps({g: {k: enc(v) for k, v in d.items()}
                           for g, d in self.to_dict().items()}, indent=indent)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PlantParams:
        """From a nested ``{group: {leaf: value}}`` or flat ``{name: value}`` mapping."""
        flat: dict[str, Any] = {}
        for k, v in data.items():
            if isinstance(v, dict):
                if k not in GROUPS:
                    raise ParameterError(f"unknown parameter group {k!r}")
                for leaf, val in v.items():
                    flat[f"{k}.{leaf}"] = float("nan") if val is None else val
            else:
                flat[k] = v
        return cls().with_dict(flat)

    @classmethod
    def from_json(cls, text: str) -> PlantParams:
        return cls.from_dict(json_object(text, ParameterError, "parameter file is not valid JSON",
                                         "parameter file must hold a JSON object"))

    def diff(self, other: PlantParams) -> dict[str, tuple[Any, Any]]:
        """Parameters that differ: name -> (self value, other value)."""
        a, b = self.flat(), other.flat()
        return {k: (a[k], b[k]) for k in a if not same_value(a[k], b[k])}


THESIS = PlantParams()
"""The thesis' nominal actuator (tables 5.1-5.4) with the chosen values documented."""
