"""An actuator description as data with units (`bench calibrate --actuator DESC`).

The bench's own plant is the thesis' BLDC actuator (`plant_rt.params`). Another rig is
described by a JSON or TOML file: what kind of motor drives it, its ratio, lead and
stroke, inertias and friction where known, and its controller's structure and gains where
known. Every value is a number in the field's unit, or ``"unknown"``; any value may come
as ``{"value": ..., "source": "..."}`` to say where it is from. `bench calibrate`
identifies what is unknown (`bench.rig.rigcal`).

    {"name": "...", "motor_kind": "stepper_chopper", "sources": ["..."],
     "lead_m": {"value": 0.005, "source": "RM1605 data sheet"}, "ratio": 1.0,
     "moving_mass_kg": "unknown", ...,
     "controller": {"structure": "unknown", "position_kp_1_s": "unknown", ...}}

The generic model the calibration fits works at the nut (`bench.sim.rigmodel`): an
equivalent mass, a force per ampere, Coulomb and viscous friction, a current offset, and
a position P + speed PI cascade with a current limit and a sample time. `model_values`
turns a description into those values (None where unknown): the equivalent mass is
m + (J_screw + J_motor N^2) (2 pi / lead)^2 (N motor turns per screw turn), the force
per ampere kt N 2 pi eta / lead.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from bench import BenchError

KINDS = ("bldc_current_loop", "dc_current_loop", "stepper_chopper")
STRUCTURES = ("position_speed_cascade", "unknown")
UNKNOWN = "unknown"


@dataclass(frozen=True)
class Field:
    """One described quantity: unit, valid range, meaning."""
    unit: str
    lo: float
    hi: float
    doc: str


MECHANISM: dict[str, Field] = {
    "ratio": Field("-", 1e-3, 1e3, "motor turns per screw turn (1: direct drive)"),
    "lead_m": Field("m", 1e-4, 0.1, "screw lead (nut travel per screw turn)"),
    "stroke_m": Field("m", 1e-4, 10.0, "usable stroke"),
    "screw_diameter_m": Field("m", 1e-3, 1.0, "screw nominal diameter"),
    "efficiency": Field("-", 0.05, 1.0, "screw efficiency eta"),
    "motor_inertia_kg_m2": Field("kg m^2", 0.0, 10.0, "motor rotor inertia"),
    "screw_inertia_kg_m2": Field("kg m^2", 0.0, 10.0, "screw inertia"),
    "moving_mass_kg": Field("kg", 0.0, 1e5, "nut and load mass moving with it"),
    "torque_constant_nm_per_a": Field("N m/A", 0.0, 100.0, "motor torque per ampere"),
    "holding_torque_nm": Field("N m", 0.0, 1e3, "stepper holding torque"),
    "coulomb_friction_n": Field("N", 0.0, 1e6, "Coulomb friction at the nut"),
    "viscous_friction_n_s_per_m": Field("N s/m", 0.0, 1e8, "viscous friction at the nut"),
    "current_offset_a": Field("A", -100.0, 100.0, "offset of the logged current"),
    "load_sign": Field("-", -1.0, 1.0, "+1: a positive logged load pushes the nut to +x, "
                       "-1: to -x (only these two, or unknown: taken as +1)"),
    "encoder_speed_window_periods": Field(
        "sample periods", 0.0, 16.0,
        "how the drive computes the logged motor speed: N >= 1 = the encoder count "
        "difference over the last N sample periods / (N T); 0 = a continuous speed "
        "sensor (the thesis' filtered encoder speed)"),
}
CONTROLLER: dict[str, Field] = {
    "position_kp_1_s": Field("1/s", 0.0, 1e5, "position gain: speed demand per position error"),
    "speed_kp_a_s_per_m": Field("A s/m", 0.0, 1e8, "speed loop proportional gain"),
    "speed_ki_a_per_m": Field("A/m", 0.0, 1e10, "speed loop integral gain"),
    "speed_feedforward": Field("-", 0.0, 1.5, "set-point speed fed forward to the speed loop"),
    "current_limit_a": Field("A", 1e-3, 1e3, "current demand saturation"),
    "sample_period_s": Field("s", 1e-5, 1.0, "controller sample time"),
    "current_loop_tau_s": Field("s", 0.0, 1.0, "current loop time constant (0: ideal)"),
}


@dataclass(frozen=True)
class Actuator:
    """A validated description: values (float or None for unknown) and their sources."""
    name: str
    motor_kind: str
    values: dict[str, float | None]
    controller: dict[str, float | None]
    structure: str
    sources: dict[str, str] = field(default_factory=dict)
    references: tuple[str, ...] = ()

    @property
    def has_current_loop(self) -> bool:
        return self.motor_kind in ("bldc_current_loop", "dc_current_loop")

    def get(self, name: str) -> float | None:
        return self.values.get(name, self.controller.get(name))

    def to_dict(self) -> dict[str, Any]:
        """The description as it would be written (unknowns as "unknown")."""
        def one(k: str, v: float | None) -> Any:
            val: Any = UNKNOWN if v is None else v
            return {"value": val, "source": self.sources[k]} if k in self.sources else val
        return {"name": self.name, "motor_kind": self.motor_kind,
                "sources": list(self.references),
                **{k: one(k, v) for k, v in self.values.items()},
                "controller": {"structure": self.structure,
                               **{k: one(k, v) for k, v in self.controller.items()}}}


def _value(raw: Any, name: str, f: Field, where: str) -> tuple[float | None, str | None]:
    """(value or None, source or None) of one entry."""
    src = None
    if isinstance(raw, dict):
        src = raw.get("source")
        if "value" not in raw:
            raise BenchError(f"{where}: {name} has no 'value'")
        raw = raw["value"]
    if raw is None or (isinstance(raw, str) and raw.strip().lower() == UNKNOWN):
        return None, src
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise BenchError(f"{where}: {name} must be a number in {f.unit} or \"unknown\", "
                         f"got {raw!r}")
    x = float(raw)
    if not math.isfinite(x) or not (f.lo <= x <= f.hi):
        raise BenchError(f"{where}: {name} = {x:g} {f.unit} is outside [{f.lo:g}, {f.hi:g}]")
    return x, src


def _group(data: dict[str, Any], table: dict[str, Field], where: str,
           sources: dict[str, str], skip: tuple[str, ...]) -> dict[str, float | None]:
    unknown = [k for k in data if k not in table and k not in skip]
    if unknown:
        raise BenchError(f"{where}: unknown entr{'y' if len(unknown) == 1 else 'ies'} "
                         f"{', '.join(unknown)} (known: {', '.join(table)})")
    out: dict[str, float | None] = {}
    for k, f in table.items():
        v, src = _value(data.get(k, UNKNOWN), k, f, where)
        out[k] = v
        if src:
            sources[k] = str(src)
    return out


def from_dict(data: dict[str, Any], where: str = "actuator") -> Actuator:
    """Validate a description (BenchError naming the entry at fault)."""
    if not isinstance(data, dict):
        raise BenchError(f"{where}: an actuator description is an object")
    kind = data.get("motor_kind")
    if kind not in KINDS:
        raise BenchError(f"{where}: motor_kind must be one of {', '.join(KINDS)}, got {kind!r}")
    sources: dict[str, str] = {}
    values = _group(data, MECHANISM, where, sources,
                    ("name", "motor_kind", "sources", "controller"))
    ctrl = data.get("controller", {}) or {}
    if not isinstance(ctrl, dict):
        raise BenchError(f"{where}: controller must be an object")
    structure = str(ctrl.get("structure", UNKNOWN))
    if structure not in STRUCTURES:
        raise BenchError(f"{where}: controller structure must be one of "
                         f"{', '.join(STRUCTURES)}, got {structure!r}")
    sign = values["load_sign"]
    if sign is not None and sign not in (-1.0, 1.0):
        raise BenchError(f"{where}: load_sign must be +1 or -1 (the direction a positive "
                         f"logged load pushes the nut) or \"unknown\", got {sign:g}")
    gains = _group(ctrl, CONTROLLER, f"{where} controller", sources, ("structure",))
    refs = data.get("sources", [])
    refs = [refs] if isinstance(refs, str) else refs
    if not isinstance(refs, list):
        raise BenchError(f"{where}: sources must be a text or a list of texts, got {refs!r}")
    return Actuator(str(data.get("name", where)), kind, values, gains, structure, sources,
                    tuple(str(r) for r in refs))


SHIPPED = {"cranfield": "cranfield_rm1605.json"}
"""Descriptions that ship with the bench, by name (`--actuator cranfield`)."""


def load(spec: str | Path) -> Actuator:
    """A description from a .json or .toml file, or a shipped one by name (SHIPPED)."""
    s = str(spec)
    if s in SHIPPED:
        text = resources.files("bench.rig.actuators").joinpath(SHIPPED[s]).read_text()
        return from_dict(json.loads(text), s)
    path = Path(s)
    if not path.exists():
        raise BenchError(f"no such actuator description: {path} (shipped: "
                         f"{', '.join(SHIPPED)})")
    try:
        if path.suffix.lower() == ".toml":
            data = tomllib.loads(path.read_text())
        elif path.suffix.lower() == ".json":
            data = json.loads(path.read_text())
        else:
            raise BenchError(f"{path}: an actuator description is .json or .toml")
    except (json.JSONDecodeError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BenchError(f"{path}: not valid {path.suffix[1:].upper()} ({exc})") from None
    except RecursionError:
        raise BenchError(f"{path}: not an actuator description (nested too deep to read)"
                         ) from None
    except IsADirectoryError:
        raise BenchError(f"{path}: a directory, not an actuator description") from None
    except OSError as exc:
        raise BenchError(f"{path}: cannot read the actuator description "
                         f"({exc.strerror or exc})") from None
    return from_dict(data, path.name)


def sensor_params(a: Actuator) -> dict[str, Any]:
    """The bench plant's sensor parameters (`plant_rt.params`) the description fixes:
    the speed estimator's window where it is known (a whole number of periods)."""
    n = a.values.get("encoder_speed_window_periods")
    if n is None:
        return {}
    if n != round(n):
        raise BenchError(f"{a.name}: encoder_speed_window_periods must be a whole number "
                         f"of sample periods, got {n:g}")
    return {"sensors.encoder_speed_window": int(n)}


def model_values(a: Actuator) -> dict[str, float | None]:
    """The generic model's values at the nut (`bench.sim.rigmodel.THETA`), None where the
    description leaves them unknown (see module doc for the conversions)."""
    v = a.values
    lead, ratio = v["lead_m"], v["ratio"] if v["ratio"] is not None else None
    mass = None
    if (lead is not None and ratio is not None and v["moving_mass_kg"] is not None
            and v["motor_inertia_kg_m2"] is not None):
        js = v["screw_inertia_kg_m2"] or 0.0
        mass = v["moving_mass_kg"] + (js + v["motor_inertia_kg_m2"] * ratio ** 2) * (
            2.0 * math.pi / lead) ** 2
    kf = None
    if (lead is not None and ratio is not None and v["torque_constant_nm_per_a"] is not None
            and a.has_current_loop):
        kf = v["torque_constant_nm_per_a"] * ratio * 2.0 * math.pi * (v["efficiency"] or 1.0) / lead
    c = a.controller
    return {"mass_kg": mass, "force_per_a_n": kf, "coulomb_n": v["coulomb_friction_n"],
            "viscous_n_s_per_m": v["viscous_friction_n_s_per_m"],
            "current_offset_a": v["current_offset_a"], "kp_1_s": c["position_kp_1_s"],
            "kv_a_s_per_m": c["speed_kp_a_s_per_m"], "ki_a_per_m": c["speed_ki_a_per_m"],
            "feedforward": c["speed_feedforward"], "current_limit_a": c["current_limit_a"],
            "current_tau_s": c["current_loop_tau_s"], "sample_period_s": c["sample_period_s"]}
