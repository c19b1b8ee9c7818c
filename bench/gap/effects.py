"""Candidate effects: small, bounded, physically parameterised augmentations of a model.

An `Effect` names a mechanism the nominal model lacks (backlash, friction growth, a
sensor lag, ...) through a few parameters, each with a unit and bounds. It acts in one
or both of two places:

- in the plant (``plant_overrides``): plant parameters changed inside the closed loop,
  so the ECU sees the consequences, as it would on hardware;
- in the log (``post``): a transformation of the logged measured columns after the run
  (a data-acquisition lag or time skew the ECU never saw).

Effects are found by name through a lazy registry (as python-can's interface table):
``EFFECTS`` maps a name to ``(module, class)``; the module is imported only when the
effect is used, and ``register()`` adds project- or user-specific effects.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from bench import BenchError
from plant_rt.params import PlantParams


@dataclass(frozen=True)
class Param:
    """One effect parameter: name (unit in the name), unit, bounds, scale and meaning.

    `log`: fitted on a logarithmic scale (bounds must be > 0). `integer_step`: the
    parameter only takes multiples of this step (a SYNC-period delay): grid-searched,
    not fitted by least squares.
    """
    name: str
    unit: str
    lo: float
    hi: float
    doc: str
    log: bool = False
    integer_step: float = 0.0

    def to_unit(self, v: float) -> float:
        """Value -> [0, 1] fitting coordinate."""
        if self.log:
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (v - self.lo) / (self.hi - self.lo)

    def from_unit(self, u: float) -> float:
        u = min(max(float(u), 0.0), 1.0)
        if self.log:
            return math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        return self.lo + u * (self.hi - self.lo)

    def dvalue_du(self, u: float) -> float:
        """d value / d unit coordinate (to carry confidence intervals to units)."""
        if self.log:
            return self.from_unit(u) * (math.log(self.hi) - math.log(self.lo))
        return self.hi - self.lo

    def grid(self) -> list[float]:
        """The values a discrete parameter takes."""
        n = int(round((self.hi - self.lo) / self.integer_step))
        return [self.lo + i * self.integer_step for i in range(n + 1)]


class Effect:
    """Base class of candidate effects. Subclasses set the class attributes and override
    `plant_overrides` and/or `post`. Instances are stateless."""
    name: ClassVar[str] = ""
    doc: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    where: ClassVar[str] = "plant"        # "plant" (in the loop) or "log" (after the run)

    def nominal(self, base: PlantParams) -> dict[str, float]:
        """The parameter values at which the effect is absent, given the nominal `base`."""
        raise NotImplementedError

    def plant_overrides(self, theta: Mapping[str, float],
                        base: PlantParams) -> dict[str, Any]:
        """Plant parameters (dotted names) to change for parameter values `theta`."""
        return {}

    def post(self, cols: dict[str, np.ndarray], theta: Mapping[str, float],
             dt: float) -> dict[str, np.ndarray]:
        """Logged measured columns after the effect (default: unchanged)."""
        return cols

    @property
    def discrete(self) -> bool:
        return all(p.integer_step > 0 for p in self.params)

    def start_points(self, base: PlantParams) -> list[dict[str, float]]:
        """Starting values of the fit: the nominal point moved inside the bounds plus a
        few spread points (the fit keeps the best)."""
        nom = self.nominal(base)
        pts = []
        for frac in (0.15, 0.5, 0.85):
            pts.append({p.name: p.from_unit(frac) for p in self.params})
        near = {p.name: p.from_unit(min(max(p.to_unit(nom[p.name]) + 0.05, 0.0), 1.0))
                for p in self.params}
        return [near] + pts

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "where": self.where, "doc": self.doc,
                "params": [{"name": p.name, "unit": p.unit, "min": p.lo, "max": p.hi,
                            "doc": p.doc} for p in self.params]}


# name -> (module, class): imported only when used
EFFECTS: dict[str, tuple[str, str]] = {
    "backlash": ("bench.gap.library", "Backlash"),
    "friction": ("bench.gap.library", "Friction"),
    "viscous": ("bench.gap.library", "Viscous"),
    "stribeck": ("bench.gap.library", "Stribeck"),
    "stiffness": ("bench.gap.library", "Stiffness"),
    "preload": ("bench.gap.library", "Preload"),
    "sensor_delay": ("bench.gap.library", "SensorDelay"),
    "lvdt_lag": ("bench.gap.library", "LvdtLag"),
    "log_skew": ("bench.gap.library", "LogSkew"),
    "lvdt_gain": ("bench.gap.library", "LvdtGain"),
    "lvdt_offset": ("bench.gap.library", "LvdtOffset"),
    "encoder_gain": ("bench.gap.library", "EncoderGain"),
    "current_offset": ("bench.gap.library", "CurrentOffset"),
    "resistance": ("bench.gap.library", "Resistance"),
    "thermal_drift": ("bench.gap.library", "ThermalDrift"),
    "kt": ("bench.gap.library", "TorqueConstant"),
    "inertia": ("bench.gap.library", "Inertia"),
    "lead": ("bench.gap.library", "Lead"),
}
_CACHE: dict[str, Effect] = {}


def register(name: str, module: str, cls: str) -> None:
    """Add (or replace) a candidate effect: `module`.`cls` must subclass `Effect`."""
    EFFECTS[name] = (module, cls)
    _CACHE.pop(name, None)


def names() -> list[str]:
    return list(EFFECTS)


def get(name: str) -> Effect:
    """The effect called `name` (BenchError naming the known ones if none)."""
    if name in _CACHE:
        return _CACHE[name]
    try:
        module, cls = EFFECTS[name]
    except KeyError:
        raise BenchError(f"unknown effect {name!r} (known: {', '.join(EFFECTS)})") from None
    try:
        obj = getattr(importlib.import_module(module), cls)()
    except (ImportError, AttributeError, TypeError) as exc:
        raise BenchError(f"effect {name!r} cannot be loaded from {module}.{cls}: {exc}") from None
    if not isinstance(obj, Effect):
        raise BenchError(f"effect {name!r}: {module}.{cls} is not a bench.gap Effect")
    _CACHE[name] = obj
    return obj


def parse_list(text: str | None) -> list[str]:
    """``"a,b,c"`` -> validated effect names (all known effects when empty/None)."""
    if not text:
        return names()
    out = []
    for part in text.split(","):
        part = part.strip()
        if part:
            get(part)
            if part not in out:
                out.append(part)
    if not out:
        raise BenchError("--effects lists no effect")
    return out
