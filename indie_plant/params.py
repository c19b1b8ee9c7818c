"""Parameters of the independent actuator: data with units, ranges and reasons.

A different actuator from the bench's thesis one on purpose: a smaller EMA (a trim or
spoiler actuator on a 270 V DC bus) with a 1:3 belt reducer, a 4 mm lead preloaded double
nut, a lighter rotor with cogging and torque ripple, and its own sensors and controller.
Values are typical catalogue values for that class (not taken from any one datasheet);
each field says why it has its value. Effects (wear, build errors, sensor errors) are
fields too, at their no-effect value; `with_dict` changes any of them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def P(default: float, unit: str, lo: float, hi: float, why: str) -> Any:  # noqa: N802
    """A parameter field: default, unit, range and the reason for the value."""
    return field(default=default, metadata={"unit": unit, "lo": lo, "hi": hi, "why": why})


@dataclass(frozen=True)
class IndieParams:
    """One independent actuator (SI units)."""
    # -- motor and drive -----------------------------------------------------------------
    kt_nm_per_a: float = P(0.9, "N m/A", 0.01, 20, "BLDC, 4 pole pairs, 270 V class")
    ke_v_s_per_rad: float = P(0.9, "V s/rad", 0.01, 20, "= kt in SI for a sine-wound motor")
    resistance_ohm: float = P(0.6, "ohm", 0.01, 20, "winding, phase to phase / 2")
    inductance_h: float = P(3e-3, "H", 1e-5, 0.1, "winding; 5 ms electrical time constant")
    inertia_kg_m2: float = P(2.5e-3, "kg m^2", 1e-5, 0.1,
                             "rotor + pulley + screw reflected to the motor; lighter than "
                             "the thesis' 4e-3 rotor alone")
    pole_pairs: float = P(4.0, "-", 1, 20, "torque ripple at 6 x electrical angle")
    ripple: float = P(0.02, "-", 0.0, 0.5, "6th-harmonic torque ripple amplitude (of kt i)")
    cogging_nm: float = P(0.03, "N m", 0.0, 2.0, "cogging torque amplitude")
    cogging_per_rev: float = P(24.0, "1/rev", 1, 200, "LCM(12 slots, 8 poles) = 24")
    supply_v: float = P(270.0, "V", 10, 1000, "aircraft HVDC bus")
    voltage_frac: float = P(1.0, "-", 0.1, 1.2, "drive voltage limit over the bus voltage: "
                            "space-vector modulation gives a line-to-line amplitude of V_dc, "
                            "and ke is line to line")
    current_limit_a: float = P(20.0, "A", 0.1, 200, "drive limit")
    current_bw_hz: float = P(1000.0, "Hz", 10, 5000, "drive current PI bandwidth (20 kHz)")
    # -- reducer, screw and nut ----------------------------------------------------------
    ratio: float = P(1.0 / 3.0, "-", 0.01, 10, "belt 1:3 (screw turns per motor turn)")
    lead_m: float = P(4e-3, "m", 1e-4, 0.05, "4 mm lead, 16 mm screw")
    nut_mass_kg: float = P(1.2, "kg", 0.01, 100, "double nut + rod + rod end")
    nut_viscous_n_s_per_m: float = P(200.0, "N s/m", 0.0, 1e5, "rod seal")
    hertz_n_per_m15: float = P(1.0e11, "N/m^1.5", 1e8, 1e14,
                               "Hertz constant of one nut half (all balls): 6 um "
                               "deflection at the 1.5 kN preload, ~3.7e8 N/m per half")
    hc_damping_s_per_m: float = P(4.0, "s/m", 0.0, 100, "Hunt-Crossley alpha: "
                                  "F = k d^1.5 (1 + alpha d'), damping ratio ~0.2")
    preload_n: float = P(1500.0, "N", 0.0, 20000, "double-nut preload (catalogue 5-10 % of "
                         "the dynamic load rating)")
    backlash_m: float = P(0.0, "m", 0.0, 1e-3, "axial wear clearance of each nut half; "
                          "eats the preload deflection first")
    # -- friction (LuGre, motor side) ----------------------------------------------------
    coulomb_nm: float = P(0.08, "N m", 0.0, 5, "seals, bearings and motor drag")
    screw_friction: float = P(0.1, "-", 0.0, 1, "screw torque per contact force: "
                              "(F_A + F_B) lead / 2 pi x this (1/eta - 1 ~ 0.1)")
    static_ratio: float = P(1.4, "-", 1.0, 5.0, "static over Coulomb friction")
    stribeck_rad_s: float = P(2.0, "rad/s", 0.01, 100, "Stribeck speed (motor side)")
    bristle_nm_per_rad: float = P(300.0, "N m/rad", 1.0, 1e5, "LuGre sigma_0")
    bristle_damping: float = P(0.5, "N m s/rad", 0.0, 100, "LuGre sigma_1")
    viscous_nm_s_per_rad: float = P(2e-4, "N m s/rad", 0.0, 1.0, "LuGre sigma_2")
    # -- sensors -------------------------------------------------------------------------
    current_adc_bits: float = P(12.0, "bit", 6, 24, "current ADC over +-40 A: 19.5 mA step")
    current_range_a: float = P(40.0, "A", 1, 1000, "current ADC full scale (+-)")
    current_noise_a: float = P(0.04, "A", 0.0, 5, "current noise before the ADC")
    encoder_counts: float = P(16384.0, "counts/rev", 16, 2**24, "14-bit absolute encoder")
    speed_window: float = P(4.0, "periods", 1, 50, "speed = angle difference over 4 periods")
    lvdt_bits: float = P(16.0, "bit", 8, 24, "LVDT ADC over +-40 mm: 1.22 um step")
    lvdt_range_m: float = P(0.04, "m", 1e-3, 1, "LVDT full scale (+-)")
    lvdt_noise_m: float = P(1.5e-6, "m", 0.0, 1e-3, "LVDT noise before the ADC")
    lvdt_tau_s: float = P(1e-3, "s", 1e-5, 0.1, "LVDT demodulator lag (first order)")
    load_noise_n: float = P(3.0, "N", 0.0, 1000, "load cell noise")
    load_step_n: float = P(0.6, "N", 0.0, 100, "load cell ADC step (16 bit over +-20 kN)")
    # -- effects and sensor errors at their no-effect value ------------------------------
    friction_scale: float = P(1.0, "-", 0.0, 20, "scales Coulomb, static and screw friction")
    viscous_scale: float = P(1.0, "-", 0.0, 1e6, "scales sigma_2")
    lvdt_gain: float = P(1.0, "-", 0.5, 2.0, "LVDT gain error")
    lvdt_offset_m: float = P(0.0, "m", -0.01, 0.01, "LVDT offset")
    encoder_gain: float = P(1.0, "-", 0.5, 2.0, "speed gain error")
    current_offset_a: float = P(0.0, "A", -5, 5, "current sensor offset")
    sensor_delay_periods: float = P(0.0, "periods", 0, 10, "LVDT and encoder delay")
    lvdt_delay_periods: float = P(0.0, "periods", 0, 10, "LVDT transport delay alone (its "
                                  "conditioner or bus), on top of sensor_delay_periods")
    lvdt_extra_lag_s: float = P(0.0, "s", 0.0, 0.1, "extra LVDT lag (a failing demodulator)")
    # -- physics switched on only for the final check (docs/gap-results.md, "The final
    # check"): off (0) by default and in every development run ----------------------------
    friction_ripple: float = P(0.0, "-", 0.0, 0.9, "Coulomb friction ripple per screw turn "
                               "(ball recirculation): amplitude as a fraction of the level")
    seal_friction_n: float = P(0.0, "N", 0.0, 2000, "rod seal's Coulomb force on the nut "
                               "(friction at the nut, not at the motor)")
    current_filter_s: float = P(0.0, "s", 0.0, 0.01, "first-order anti-alias filter of the "
                                "logged current sensor")
    # -- integration ---------------------------------------------------------------------
    sync_period_s: float = P(1e-3, "s", 1e-4, 0.1, "SYNC period")
    substeps: float = P(100.0, "-", 10, 2000, "mechanical sub-steps per period (10 us: "
                        "the nut-on-contact mode is ~4 kHz)")
    noise: float = P(1.0, "-", 0, 1, "white sensor noise on (1) or off (0); the ADC, "
                     "encoder and LVDT steps stay")

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            m = f.metadata
            if not (isinstance(v, (int, float)) and math.isfinite(v) and m["lo"] <= v <= m["hi"]):
                raise ValueError(f"{f.name} = {v!r} outside [{m['lo']}, {m['hi']}] {m['unit']}")

    def with_dict(self, over: dict[str, float]) -> IndieParams:
        names = {f.name for f in dataclasses.fields(self)}
        bad = sorted(set(over) - names)
        if bad:
            raise ValueError(f"unknown indie parameter(s): {', '.join(bad)}")
        return dataclasses.replace(self, **{k: float(v) for k, v in over.items()})

    def with_assignments(self, assignments: list[str]) -> IndieParams:
        over = {}
        for a in assignments:
            name, sep, value = a.partition("=")
            if not sep:
                raise ValueError(f"--set needs NAME=VALUE, got {a!r}")
            over[name.strip()] = float(value)
        return self.with_dict(over)

    @property
    def travel_per_rad(self) -> float:
        """Nut travel per motor radian (m/rad)."""
        return self.ratio * self.lead_m / (2.0 * math.pi)

    def vector(self) -> np.ndarray:
        return np.array([float(getattr(self, n)) for n in NAMES])


# The field order is the vector layout physics.py compiles with; numba's on-disk cache is
# keyed on physics.py alone, so after adding or moving a field here, touch physics.py.
NAMES = tuple(f.name for f in dataclasses.fields(IndieParams))
IDX = {n: i for i, n in enumerate(NAMES)}


def table() -> list[tuple[str, str, float, str]]:
    """(name, unit, default, why) of every parameter."""
    d = IndieParams()
    return [(f.name, f.metadata["unit"], getattr(d, f.name), f.metadata["why"])
            for f in dataclasses.fields(IndieParams)]
