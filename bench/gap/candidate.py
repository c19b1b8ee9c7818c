"""What a candidate effect is: small, bounded, physically parameterised augmentations of a
model (`Param`, `Effect`); the built-in ones are in `bench.gap.library`, found by name
through `bench.gap.effects`.

An `Effect` names a mechanism the nominal model lacks (backlash, friction growth, a
sensor lag, ...) through a few parameters, each with a unit and bounds. It acts in one
or both of two places:

- in the plant (``plant_overrides``): plant parameters changed inside the closed loop,
  so the ECU sees the consequences, as it would on hardware;
- in the log (``post``): a transformation of the logged measured columns after the run
  (a data-acquisition lag or time skew the ECU never saw).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from plant_rt.params import PlantParams

WEAR_FRACTIONS = (0.5, 0.1)
"""Start points of an effect whose parameters fall with wear (``wear_direction = "down"``),
as fractions of the nominal (docs/gap.md, "Candidate effects and their families")."""


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
    physical_bounds: bool = False
    """The bounds are the quantity's own limits (a share from 0 to 1), not the family's:
    a fit on one of them is no sign of an effect beyond the family (`fit.at_bounds`)."""

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

    def scaled(self, k: float) -> Param:
        """The same parameter with both bounds times `k` (> 0; `bound_scale`)."""
        return dataclasses.replace(self, lo=self.lo * k, hi=self.hi * k)

    def dvalue_du(self, u: float) -> float:
        """d value / d unit coordinate (to carry confidence intervals to units)."""
        if self.log:
            return self.from_unit(u) * (math.log(self.hi) - math.log(self.lo))
        return self.hi - self.lo

    def grid(self) -> list[float]:
        """The values a discrete parameter takes."""
        n = int(round((self.hi - self.lo) / self.integer_step))
        return [self.lo + i * self.integer_step for i in range(n + 1)]


@functools.cache
def _thesis_value(name: str) -> float:
    return float(PlantParams().get(name))


def bound_scale(base: PlantParams, name: str) -> float:
    """Factor from the thesis' actuator to the model `base` for the plant parameter
    `name`: base's value / the thesis' value (exactly 1 at the thesis' value; 1 when
    either is not a positive number). Bounds written as a range around the thesis'
    actuator (a 5 mm lead, a 4e-3 kg m^2 rotor) are scaled by it, so that another
    actuator's value lies where the thesis' lies in them (the library's effects,
    `_Single.for_model`, and the calibration, `bench.gap.calibrate.PlantSet`)."""
    v, ref = float(base.get(name)), _thesis_value(name)
    if not (math.isfinite(v) and math.isfinite(ref) and v > 0 and ref > 0):
        return 1.0
    return v / ref


class Effect:
    """Base class of candidate effects. Subclasses set the class attributes and override
    `plant_overrides` and/or `post`. Instances are stateless."""
    name: ClassVar[str] = ""
    doc: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    where: ClassVar[str] = "plant"        # "plant" (in the loop) or "log" (after the run)
    # the direction the parameters move with wear: "down" (below the nominal, e.g. a
    # preload lost as the raceways wear) adds start points at `WEAR_FRACTIONS` of the
    # nominal; None (default): no direction declared
    wear_direction: ClassVar[str | None] = None

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

    def for_model(self, base: PlantParams) -> Effect:
        """The effect as fitted on the start model `base`: itself by default; an effect
        whose bounds are a range around the thesis' actuator returns a copy with the range
        moved to `base`'s value (`bound_scale`) when that value lies outside it. The fit
        calls it."""
        return self

    def loop_delays(self, theta: Mapping[str, float], dt: float) -> tuple[int, int]:
        """Whole SYNC periods by which the LVDT and the encoder are read later in the
        loop, each alone (`bench.gap.delays`; default: none)."""
        return (0, 0)

    def available(self, base: PlantParams) -> bool:
        """Whether the effect has a place in the model `base` (default: yes); one that
        has not is not tried (e.g. a drive-side current offset where the model's logged
        current is a channel of its own: its log-side twin is the candidate there)."""
        return True

    def in_log(self, base: PlantParams) -> bool:
        """Whether `post` applies for the nominal model `base` (default: ``where``). An
        effect whose place depends on the model (an LVDT lag in or after the loop) says
        so here."""
        return self.where == "log"

    @property
    def discrete(self) -> bool:
        return all(p.integer_step > 0 for p in self.params)

    def start_points(self, base: PlantParams) -> list[dict[str, float]]:
        """Starting values of the fit: the nominal point moved inside the bounds plus a
        few spread points (the fit keeps the best); for an effect that declares
        ``wear_direction = "down"``, also the nominal times each of `WEAR_FRACTIONS`
        (clipped to the bounds), where that is below the nominal (a nominal of 0 has no
        loss to start from: nothing is added)."""
        nom = self.nominal(base)
        pts = []
        for frac in (0.15, 0.5, 0.85):
            pts.append({p.name: p.from_unit(frac) for p in self.params})
        near = {p.name: p.from_unit(min(max(p.to_unit(nom[p.name]) + 0.05, 0.0), 1.0))
                for p in self.params}
        if self.wear_direction == "down":
            for frac in WEAR_FRACTIONS:
                worn = {p.name: min(max(nom[p.name] * frac, p.lo), p.hi) for p in self.params}
                if any(worn[p.name] < nom[p.name] for p in self.params):
                    pts.append(worn)
        return [near] + pts

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "where": self.where, "doc": self.doc,
                "params": [{"name": p.name, "unit": p.unit, "min": p.lo, "max": p.hi,
                            "doc": p.doc} for p in self.params]}
