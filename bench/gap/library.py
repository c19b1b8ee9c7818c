"""The built-in candidate effects (docs/gap.md, which unmodelled effect causes the gap).

Each is a bounded augmentation of the nominal plant with physical units. Plant-side
effects change `PlantParams` inside the closed loop; log-side effects transform the
logged columns after the run. Bounds are wide physical ranges, not the benchmark's.

Known near-equivalences on a bus log (no voltage, no force sensor logged):
- torque constant error == current-sensor gain error (the drive regulates the sensed
  current; only torque per sensed ampere is observable), so there is one candidate, `kt`;
- LVDT gain error ~ screw lead error (both scale LVDT travel per motor radian; they
  differ only through the nut friction reflected by the lead, a few per cent of torque).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from bench.gap.candidate import Effect, Param, bound_scale
from bench.gap.resim import first_order
from plant_rt import kernel as K
from plant_rt.model import param_vector
from plant_rt.params import PlantParams

MEASURED_COLS = ("current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m")


class _Single(Effect):
    """An effect that sets one plant parameter to the fitted value."""
    target: str = ""

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {self.params[0].name: float(base.get(self.target))}

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        return {self.target: theta[self.params[0].name]}

    scales_with_model: ClassVar[bool] = False
    """Bounds written around the thesis' actuator's value: scaled to the start model's
    value (`bound_scale`), so that the candidate moves both ways from any actuator's
    nominal (a value on an edge could move one way only; docs/gap.md, "Calibration"). The calibration scales its ranges the same way."""

    def for_model(self, base: PlantParams) -> Effect:
        """The effect with its first parameter's class bounds (the range around the
        thesis' actuator) scaled to `base`: the same whether `self` is the registered
        effect or a copy already fitted on a model (a refit of a fitted candidate scaled
        the lead's range twice, 2.56-3.84 mm for a 4 mm model, and pinned the refit on its
        bound)."""
        k = bound_scale(base, self.target) if self.scales_with_model else 1.0
        own = type(self).params[0]
        if k == 1.0 and self.params[0] == own:
            return self
        eff = copy.copy(self)
        eff.params = (own.scaled(k) if k != 1.0 else own,   # type: ignore[misc]
                      *self.params[1:])
        return eff


NUT_SHARE = Param("nut_friction_share", "-", 0.0, 1.0,
                  "share of the model's nut Coulomb friction F_s (eq. 5.31) that acts at the "
                  "nut; the rest acts at the screw (C_fs of eq. 5.14), the same torque at the "
                  "motor (F_s p / 2 pi)", physical_bounds=True)
"""Where the Coulomb friction acts, at the nut (loading the balls) or at the screw (on
the motor's side of the contacts). A stiff preloaded nut hides the split: both give the
same motor torque and a deflection below the encoder's resolution. A compliant or loose
nut shows it (the nut's friction deflects the contacts by F_s / k, or holds the nut while
the screw crosses a clearance), and so does a grown friction (a larger F_s / k). A healthy
log cannot calibrate it. When the diagnosis is told that the model's split is unknown
(`Problem.friction_split`, `bench gap --friction-split unknown`), the effects that show it
(stiffness, preload, backlash, friction) fit it as a second parameter (`with_nut_share`);
otherwise they keep the model's split (docs/gap.md, "Inputs")."""

FRICTION_SPLITS = ("model", "unknown")
"""How a diagnosis treats where the model's Coulomb friction acts: "model" (the model's
split is known, as the thesis' for the bench's own plant: nothing added) or "unknown" (a
datasheet gives a total friction, not where it acts: the effects that show it fit
`NUT_SHARE`, `with_nut_share`)."""

SPLIT_NOTE = {
    "model": "the model's (where its Coulomb friction acts, nut or screw, is taken as known)",
    "unknown": "unknown: stiffness, preload, backlash and friction also fit the share of the "
               "nut's Coulomb friction that acts at the nut (nut_friction_share, 1 = the "
               "model's split)"}
"""What a diagnosis's JSON says of each friction split."""


def nut_split(share: float, base: PlantParams) -> dict[str, float]:
    """Plant overrides that keep `share` of `base`'s nut Coulomb friction F_s at the nut
    (eq. 5.31) and move the rest to the screw's Coulomb torque C_fs (eq. 5.14) at the
    work-equivalent F_s p / 2 pi, so the Coulomb torque the motor sees is unchanged."""
    s = base.screw
    moved = (1.0 - share) * s.nut_static_friction_n
    return {"screw.nut_static_friction_n": s.nut_static_friction_n - moved,
            "screw.support_static_friction_nm": s.support_static_friction_nm
            + moved * s.lead_m / (2.0 * np.pi)}


class _NutShare(_Single):
    """An effect that shows where the nut's Coulomb friction acts. Registered with its own
    parameter only; `with_share` gives the copy that also fits NUT_SHARE (nominal 1, the
    model's split). A `theta` that carries the share applies it, whichever copy reads it,
    so a fit re-simulated from the effect's name is the fit."""

    def _shares(self) -> bool:
        return any(p.name == NUT_SHARE.name for p in self.params)

    def with_share(self) -> Effect:
        if self._shares():
            return self
        eff = copy.copy(self)
        eff.params = (*self.params, NUT_SHARE)   # type: ignore[misc]
        return eff

    def nominal(self, base: PlantParams) -> dict[str, float]:
        out = super().nominal(base)
        return {**out, NUT_SHARE.name: 1.0} if self._shares() else out

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        out = super().plant_overrides(theta, base)
        share = theta.get(NUT_SHARE.name, 1.0)
        return {**out, **nut_split(share, base)} if share != 1.0 else out

    def start_points(self, base: PlantParams) -> list[dict[str, float]]:
        """Effect.start_points of the effect's own parameter; with the share, each of them
        with the model's split (share 1) and with all of the nut's friction at the screw
        (share 0)."""
        if not self._shares():
            return super().start_points(base)
        alone = copy.copy(self)
        alone.params = self.params[:1]   # type: ignore[misc]
        own = self.params[0].name
        pts = [pt[own] for pt in super(_NutShare, alone).start_points(base)]
        return [{own: v, NUT_SHARE.name: s} for s in (1.0, 0.0) for v in pts]


def with_nut_share(eff: Effect) -> Effect:
    """`eff` fitting NUT_SHARE as well when it shows where the nut's friction acts (an
    effect built on `_NutShare`: stiffness, preload, backlash, friction), else `eff`."""
    return eff.with_share() if isinstance(eff, _NutShare) else eff


class Backlash(_NutShare):
    name = "backlash"
    doc = "lost motion between screw and nut (eq. 5.19-5.24)"
    params = (Param("backlash_m", "m", 0.0, 300e-6, "total backlash b_max"),)
    target = "effects.backlash_m"


class Friction(_NutShare):
    name = "friction"
    doc = "static/Coulomb friction torques and forces scaled (wear, lubricant loss)"
    params = (Param("friction_scale", "-", 0.2, 8.0,
                    "scale of all static/Coulomb friction (1 = thesis table 5.4)", log=True),)
    target = "effects.friction_scale"


def nominal_viscous_motor_side(base: PlantParams) -> float:
    """Motor-side equivalent viscous coefficient of `base` (N m s/rad): the screw-shaft
    term c_s w_m (eq. 5.13) reflected through the reducer, tau / eta."""
    p = param_vector(base)
    return float(p[K.P_CVISC] * base.effects.viscous_scale * p[K.P_TAU] / p[K.P_ETA])


class FrictionLevels(_NutShare):
    name = "friction_levels"
    doc = ("every friction level scaled together by one factor of the model's: the static "
           "and Coulomb torques and forces, the load-dependent rolling friction and the "
           "viscous coefficients (a lubricant lost or contaminated raises them all)")
    params: ClassVar[tuple[Param, ...]] = (
        Param("friction_levels_scale", "-", 0.2, 8.0,
              "factor on the model's friction levels (1 = the model's)", log=True),)
    target = "effects.friction_scale"
    factors: ClassVar[tuple[str, ...]] = ("friction_levels_scale",) * 3
    """The parameter that scales each of: Coulomb (CS, FS), the load-dependent rolling
    friction (f_v, eq. 5.13 and 5.31) and the viscous coefficients."""

    def nominal(self, base: PlantParams) -> dict[str, float]:
        out = {q.name: 1.0 for q in self.params if q.name != NUT_SHARE.name}
        return {**out, NUT_SHARE.name: 1.0} if self._shares() else out

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        a, b, c = (theta[k] for k in self.factors)
        e = base.effects
        out: dict[str, Any] = {"effects.friction_scale": e.friction_scale * a,
                               "screw.rolling_friction": min(base.screw.rolling_friction * b,
                                                             0.1),
                               "effects.viscous_scale": min(e.viscous_scale * c, 1e6)}
        share = theta.get(NUT_SHARE.name, 1.0)
        return {**out, **nut_split(share, base)} if share != 1.0 else out

    def start_points(self, base: PlantParams) -> list[dict[str, float]]:
        if len(self.params) - self._shares() == 1:
            return super().start_points(base)
        pts = [{q.name: 1.0 for q in self.params}]   # the model's, then 3 spread points
        for frac in (0.15, 0.5, 0.85):
            pts.append({q.name: q.from_unit(frac) for q in self.params})
        return [{k: (1.0 if k == NUT_SHARE.name and k in pt else v) for k, v in pt.items()}
                for pt in pts]


class FrictionApart(FrictionLevels):
    name = "friction_apart"
    doc = ("the friction levels scaled apart: the static and Coulomb torques and forces, the "
           "load-dependent rolling friction and the viscous coefficients, each by its own "
           "factor of the model's")
    params = (Param("coulomb_scale", "-", 0.2, 8.0, "factor on the model's static and "
                    "Coulomb levels", log=True),
              Param("rolling_scale", "-", 0.2, 8.0, "factor on the model's load-dependent "
                    "rolling friction f_v", log=True),
              Param("viscous_factor", "-", 0.2, 8.0, "factor on the model's viscous "
                    "coefficients", log=True))
    factors = ("coulomb_scale", "rolling_scale", "viscous_factor")


class Viscous(Effect):
    name = "viscous"
    doc = ("viscous friction growth, as a motor-side coefficient (N m s/rad) added to the "
           "nominal one (applied through effects.viscous_scale)")
    params = (Param("viscous_nm_s_per_rad", "N m s/rad", 0.0, 0.02,
                    "motor-side viscous coefficient (nominal ~2e-8)"),)

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {"viscous_nm_s_per_rad": nominal_viscous_motor_side(base)}

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        per_unit = nominal_viscous_motor_side(base) / base.effects.viscous_scale
        scale = theta["viscous_nm_s_per_rad"] / per_unit
        return {"effects.viscous_scale": float(min(max(scale, 0.0), 1e6))}


class Stribeck(Effect):
    name = "stribeck"
    doc = "Stribeck friction: static over Coulomb overshoot and its decay speed (eq. 5.13)"
    params = (Param("stribeck_amplitude", "-", 0.0, 3.0,
                    "static/Coulomb overshoot (0.1 nominal)"),
              Param("stribeck_velocity_rad_s", "rad/s", 0.05, 50.0,
                    "screw speed of the overshoot's decay (1 nominal)", log=True))

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {"stribeck_amplitude": base.screw.stribeck_amplitude,
                "stribeck_velocity_rad_s": base.screw.stribeck_velocity_rad_s}

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        return {"screw.stribeck_amplitude": theta["stribeck_amplitude"],
                "screw.stribeck_velocity_rad_s": theta["stribeck_velocity_rad_s"]}


class Stiffness(_NutShare):
    name = "stiffness"
    doc = "finite (lower) screw-nut contact stiffness k* (eq. 5.21)"
    params = (Param("contact_stiffness_n_per_m", "N/m", 1e5, 1.5e8,
                    "contact stiffness without preload (1e8 nominal; the fast mode's 20 us "
                    "step is stable up to ~2e8)", log=True),)
    target = "screw.contact_stiffness_n_per_m"


class Preload(_NutShare):
    name = "preload"
    doc = ("double-nut preload F_pr: stiffer contacts (eq. 5.21, or the Hertzian law when the "
           "model declares screw.hertz_reference_preload_n), more rolling friction, the "
           "preload's drag (eq. 5.13, 5.31: f_v on the contact forces) (eq. 5.29)")
    params = (Param("preload_n", "N", 0.0, 8000.0, "preload force"),)
    target = "effects.preload_n"
    wear_direction = "down"     # a ball screw's preload is lost as raceways and balls wear


class SensorDelay(_Single):
    name = "sensor_delay"
    doc = "pure delay of LVDT and encoder samples, seen by the ECU (whole SYNC periods)"
    params = (Param("sensor_delay_s", "s", 0.0, 0.008, "delay", integer_step=0.001),)
    target = "effects.sensor_delay_s"


class LvdtLag(Effect):
    name = "lvdt_lag"
    doc = ("first-order lag added to the LVDT: in the loop when the model's LVDT "
           "conditioner is first order (sensors.lvdt_time_constant_s > 0: its time "
           "constant grows by the lag, as the ECU sees it), else of the logged signal "
           "(an acquisition filter; not in the loop)")
    where = "log"
    params = (Param("lvdt_lag_s", "s", 0.0, 0.05, "time constant"),)

    @staticmethod
    def in_loop(base: PlantParams) -> bool:
        """The model's LVDT conditioner is a first-order lag the controller reads
        through (`sensors.lvdt_time_constant_s` > 0)."""
        return base.sensors.lvdt_time_constant_s > 0.0

    def in_log(self, base: PlantParams) -> bool:
        return not self.in_loop(base)

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {"lvdt_lag_s": 0.0}

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        if not self.in_loop(base):
            return {}
        # a slower conditioner in series with the model's: the time constants add (the
        # same low-frequency phase lag, sum tau w, as the two first-order poles)
        tau = base.sensors.lvdt_time_constant_s + theta["lvdt_lag_s"]
        return {"sensors.lvdt_time_constant_s": float(min(tau, 0.1))}

    def post(self, cols: dict[str, np.ndarray], theta: Mapping[str, float],
             dt: float) -> dict[str, np.ndarray]:
        out = dict(cols)
        out["position_m"] = first_order(cols["position_m"], dt, theta["lvdt_lag_s"])
        return out


class LogSkew(Effect):
    name = "log_skew"
    doc = ("time skew of the logged measurements behind the logged set-point and demand "
           "(acquisition latency; not in the loop), whole SYNC periods")
    where = "log"
    params = (Param("log_skew_s", "s", 0.0, 0.008, "skew", integer_step=0.001),)

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {"log_skew_s": 0.0}

    def post(self, cols: dict[str, np.ndarray], theta: Mapping[str, float],
             dt: float) -> dict[str, np.ndarray]:
        d = int(round(theta["log_skew_s"] / dt))
        if d <= 0:
            return cols
        out = dict(cols)
        for c in MEASURED_COLS:
            if c in cols:
                v = cols[c]
                out[c] = np.concatenate([np.full(d, v[0]), v[:-d]])[:len(v)]
        return out


class LvdtGain(_Single):
    name = "lvdt_gain"
    doc = "LVDT scale error (in the loop)"
    params = (Param("lvdt_gain", "-", 0.8, 1.25, "LVDT gain (1 = exact)"),)
    target = "sensors.lvdt_gain"
    scales_with_model = True


class LvdtOffset(_Single):
    name = "lvdt_offset"
    doc = "LVDT zero offset (in the loop)"
    params = (Param("lvdt_offset_m", "m", -1e-3, 1e-3, "offset"),)
    target = "sensors.lvdt_offset_m"


class EncoderGain(_Single):
    name = "encoder_gain"
    doc = "encoder speed scale error (in the loop)"
    params = (Param("encoder_gain", "-", 0.8, 1.25, "speed gain (1 = exact)"),)
    target = "sensors.encoder_gain"
    scales_with_model = True


class CurrentOffset(_Single):
    name = "current_offset"
    doc = ("offset of the drive's current sensor, in the loop (the drive regulates the "
           "sensed current, so the true current is off by it); where the model's logged "
           "current is a channel of its own, its offset is `current_offset_log`")
    params = (Param("current_offset_a", "A", -2.0, 2.0, "offset"),)
    target = "sensors.current_offset_a"

    def available(self, base: PlantParams) -> bool:
        return bool(base.sensors.current_in_loop)


class Resistance(_Single):
    name = "resistance"
    doc = "winding resistance at the reference temperature"
    params = (Param("resistance_ohm", "ohm", 0.05, 4.0, "R (0.4 nominal)", log=True),)
    target = "motor.resistance_ohm"
    scales_with_model = True


class ThermalDrift(_Single):
    name = "thermal_drift"
    doc = "winding resistance rising with winding temperature (eq. 5.5 coupled)"
    params = (Param("resistance_tempco_per_k", "1/K", 0.0, 0.01,
                    "temperature coefficient (copper 0.00393)"),)
    target = "motor.resistance_tempco_per_k"


class TorqueConstant(_Single):
    name = "kt"
    doc = ("torque per sensed ampere: torque-constant error or, equivalently on a bus log, "
           "current-sensor gain error")
    params = (Param("kt_nm_per_a", "N m/A", 0.6, 3.0, "torque constant (1.5 nominal)",
                    log=True),)
    target = "motor.kt_nm_per_a"
    scales_with_model = True


class Inertia(_Single):
    name = "inertia"
    doc = "rotor (motor-side) inertia error"
    params = (Param("inertia_kg_m2", "kg m^2", 1e-3, 2e-2, "rotor inertia (4e-3 nominal)",
                    log=True),)
    target = "motor.inertia_kg_m2"
    scales_with_model = True


class Lead(_Single):
    name = "lead"
    doc = "screw lead (pitch) error"
    params = (Param("lead_m", "m", 4.0e-3, 6.0e-3, "lead (5e-3 nominal)"),)
    target = "screw.lead_m"
    scales_with_model = True


# The built-in candidates in the diagnosis' order (`bench.gap.effects.EFFECTS` is built
# from this tuple, keyed by each class's `name`).
BUILTIN: tuple[type[Effect], ...] = (
    Backlash, Friction, FrictionLevels, FrictionApart, Viscous, Stribeck, Stiffness, Preload,
    SensorDelay,
    LvdtLag, LogSkew, LvdtGain, LvdtOffset, EncoderGain, CurrentOffset, Resistance,
    ThermalDrift, TorqueConstant, Inertia, Lead)
