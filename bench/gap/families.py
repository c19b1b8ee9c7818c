"""Effect families: what a verdict names (docs/gap.md, "Candidate effects and their families").

A candidate is one parameterisation of a mechanism; a family is the mechanism. Friction
growth is one family whatever its law (the Coulomb and static levels, every level
together, the viscous coefficient, the Stribeck peak); a sensor's timing is one family
whatever the sensor and wherever it is late (in the loop or in the log alone, a delay or
a first-order lag); the current's offset is one family on the drive's sensor or on the
logger's. The verdict names the family, with its size where the family has one
("friction x2.4 [2.1, 2.7]"), and the member that fitted best second ("Coulomb and
static levels"). An actuator whose friction follows another law than the model's is
still found to have more friction; which law fits it best is the secondary finding.

Each family also says which way wear moves it and how far a build or a sensor error
plausibly goes (`suspect`): a fitted value beyond that is reported as suspect rather
than taken as found (a friction at x0.2 of a calibrated model is no wear: something
else was absorbed). The limits are physical judgements written down before the
benchmarks were run (below, with their reasons); no benchmark result set them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

FAMILY_OF: dict[str, str] = {
    "friction": "friction", "friction_levels": "friction", "friction_apart": "friction",
    "viscous": "friction", "stribeck": "friction",
    "backlash": "backlash", "stiffness": "stiffness", "preload": "preload",
    "sensor_delay": "delay", "lvdt_delay": "delay", "encoder_delay": "delay",
    "log_skew": "delay", "lvdt_delay_log": "delay", "encoder_delay_log": "delay",
    "current_delay_log": "delay", "lvdt_lag": "delay",
    "lvdt_gain": "lvdt_gain", "encoder_gain": "encoder_gain",
    "current_gain_log": "current_gain",
    "lvdt_offset": "lvdt_offset",
    "current_offset": "current_offset", "current_offset_log": "current_offset",
    "resistance": "resistance", "thermal_drift": "resistance",
    "kt": "kt", "inertia": "inertia", "lead": "lead",
}
"""Candidate effect -> its family (an effect registered later is its own family)."""

LABEL: dict[str, str] = {
    "friction": "friction", "backlash": "backlash", "stiffness": "contact stiffness",
    "preload": "preload", "delay": "sensor delay", "lvdt_gain": "LVDT gain",
    "encoder_gain": "encoder speed gain", "current_gain": "logged current gain",
    "lvdt_offset": "LVDT offset", "current_offset": "current offset",
    "resistance": "winding resistance", "kt": "torque constant", "inertia": "rotor inertia",
    "lead": "screw lead",
}

SUBFORM: dict[str, str] = {
    "friction": "Coulomb and static levels",
    "friction_levels": "every level together (Coulomb, static, load-dependent, viscous)",
    "friction_apart": "Coulomb, load-dependent and viscous levels apart",
    "viscous": "viscous", "stribeck": "Stribeck peak (static over Coulomb)",
    "sensor_delay": "LVDT and encoder, in the loop", "lvdt_delay": "LVDT, in the loop",
    "encoder_delay": "encoder, in the loop", "log_skew": "every logged measurement",
    "lvdt_delay_log": "logged LVDT only", "encoder_delay_log": "logged encoder only",
    "current_delay_log": "logged current only", "lvdt_lag": "LVDT first-order lag",
    "current_offset": "drive's sensor, in the loop",
    "current_offset_log": "logged current only",
    "thermal_drift": "rising with the winding's temperature",
}


def family(effect: str) -> str:
    """The family of candidate `effect` (its own name when it belongs to none)."""
    return FAMILY_OF.get(effect, effect)


def families(candidate: str) -> tuple[str, ...]:
    """The families of a candidate name ("a+b"), sorted, each once."""
    return tuple(sorted({family(e) for e in candidate.split("+") if e}))


def family_name(candidate: str) -> str:
    """"backlash+friction" for "friction_levels+backlash"."""
    return "+".join(families(candidate))


@dataclass(frozen=True)
class Plausible:
    """How far a family's parameter plausibly moves from the model's value.

    `below` / `above`: the lowest / highest ratio to the model's value that wear, a build
    tolerance or a sensor's class makes plausible (None: no limit that way); `absolute`:
    the largest plausible change in the parameter's unit (for a zero-nominal one).
    `why_below` / `why_above`: the reason, printed with the value."""
    below: float | None = None
    above: float | None = None
    absolute: float | None = None
    why_below: str = ""
    why_above: str = ""


PLAUSIBLE: dict[str, Plausible] = {
    # wear, contamination and lost lubricant raise friction; a calibrated level a third
    # lower is already more than a temperature change of the grease gives
    "friction_scale": Plausible(below=0.7, why_below="lower than any wear makes it"),
    "friction_levels_scale": Plausible(below=0.7, why_below="lower than any wear makes it"),
    "coulomb_scale": Plausible(below=0.7, why_below="lower than any wear makes it"),
    "rolling_scale": Plausible(below=0.7, why_below="lower than any wear makes it"),
    "viscous_factor": Plausible(below=0.7, why_below="lower than any wear makes it"),
    # raceway and ball wear only lower a preload (catalogue: lost with running-in and wear)
    "preload_n": Plausible(above=1.3, why_above="above the built preload: wear only lowers "
                           "a preload"),
    # wear and a lost preload soften a nut; a stiffer one than built is no wear
    "contact_stiffness_n_per_m": Plausible(above=1.3, why_above="stiffer than built: wear "
                                           "only softens a nut"),
    # a winding's resistance rises (temperature, a damaged strand or joint); 20 % below its
    # cold value is beyond a copper tolerance, 5 x above it beyond heating and a bad joint
    "resistance_ohm": Plausible(below=0.8, above=5.0, why_below="below the winding's own "
                                "resistance", why_above="beyond a winding's heating and a "
                                "damaged joint"),
    # no screw's lead changes in service, and its tolerance is hundredths of a per cent
    # (ISO 3408's coarsest transport class: ~0.07 %): a lead 3 % off is a wrong datasheet
    # or, on a log, an LVDT gain (the product is what the kinematics fix)
    "lead_m": Plausible(below=0.97, above=1.03, why_below="beyond any screw's lead "
                        "tolerance", why_above="beyond any screw's lead tolerance"),
    # a torque constant within +-30 % of its datasheet (demagnetisation lowers it some %)
    "kt_nm_per_a": Plausible(below=0.7, above=1.3, why_below="beyond a motor's tolerance "
                             "and demagnetisation", why_above="beyond a motor's tolerance"),
    "inertia_kg_m2": Plausible(below=0.4, above=2.5, why_below="less than the rotor alone",
                               why_above="more than any coupling adds"),
    # sensor classes: 10 % gain is ten times an LVDT's or an encoder channel's class
    "lvdt_gain": Plausible(below=0.9, above=1.1, why_below="beyond a sensor's class",
                           why_above="beyond a sensor's class"),
    "encoder_gain": Plausible(below=0.9, above=1.1, why_below="beyond a sensor's class",
                              why_above="beyond a sensor's class"),
    "current_gain_log": Plausible(below=0.9, above=1.1, why_below="beyond a sensor's class",
                                  why_above="beyond a sensor's class"),
    # offsets: half a millimetre of LVDT zero, 1 A (5 % of a 20 A channel)
    "lvdt_offset_m": Plausible(absolute=0.5e-3, why_above="larger than an LVDT's zero "
                               "tolerance"),
    "current_offset_a": Plausible(absolute=1.0, why_above="larger than a current "
                                  "sensor's zero tolerance"),
    "current_offset_log_a": Plausible(absolute=1.0, why_above="larger than a current "
                                      "sensor's zero tolerance"),
}
"""Plausible ranges per fitted parameter (module doc)."""


def _fmt_ratio(r: float) -> str:
    return f"x{r:.2g}" if r < 10 else f"x{r:.0f}"


def suspect(params: Mapping[str, Mapping[str, Any]], nominal: Mapping[str, float]
            ) -> list[str]:
    """Why a fit's values are implausible: per parameter beyond its `PLAUSIBLE` range,
    one line ("friction_scale x0.2 of the model's: lower than any wear makes it").
    `params`: the fit's {name: {value, ...}}; `nominal`: the model's values."""
    out = []
    for name, d in params.items():
        rule = PLAUSIBLE.get(name)
        v, v0 = d.get("value"), nominal.get(name)
        if rule is None or v is None or v0 is None or not math.isfinite(v):
            continue
        if rule.absolute is not None:
            if abs(v - v0) > rule.absolute:
                out.append(f"{name} {v - v0:+.3g} {d.get('unit', '')} from the model's: "
                           f"{rule.why_above}".replace("  ", " "))
            continue
        if not (v0 > 0):
            continue
        r = v / v0
        if rule.below is not None and r < rule.below:
            out.append(f"{name} {_fmt_ratio(r)} of the model's: {rule.why_below}")
        elif rule.above is not None and r > rule.above:
            out.append(f"{name} {_fmt_ratio(r)} of the model's: {rule.why_above}")
    return out


EDGE_NOTE = "at the edge of the family: the effect may be larger or of another form"


def ties_across(chosen: str, tied: Iterable[str]) -> list[str]:
    """The tied candidates that name other families than `chosen` does (a tie between
    two forms of one family is no doubt about the family)."""
    mine = families(chosen)
    return [t for t in tied if families(t) != mine]
