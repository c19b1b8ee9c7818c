"""Calibration of the nominal model to a healthy log (`bench calibrate`).

A different actuator has different parameters from the thesis' tables; diagnosing it
against the thesis would report its build tolerances as a gap. Calibration fits the
nominal model's uncertain parameters to a healthy log of that actuator, so later logs
are diagnosed against its own baseline (`bench gap --nominal CALIBRATION.json`).

The fit is the diagnosis' closed-loop least squares with all uncertain parameters at
once and a Gaussian prior on each (its tolerance, below) that keeps aliased parameters
well posed: on a log without a force measurement, torque constant and inertia act
through their ratio, and screw lead and LVDT gain through their product, so the data fix
the ratio/product and the prior shares it out. The output states this.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench import BenchError
from bench.gap import resim as R
from bench.gap.effects import Effect, Param
from bench.gap.fit import fit
from bench.gap.problem import build
from bench.trace import Trace
from plant_rt.params import PlantParams, resolve


@dataclass(frozen=True)
class Uncertain:
    """One calibrated parameter: plant name, fit bounds, scale and prior tolerance (1 sd,
    relative to the nominal value, or absolute in the unit for zero-nominal ones)."""
    name: str
    lo: float
    hi: float
    log: bool
    tol: float
    relative: bool = True


UNCERTAIN: dict[str, Uncertain] = {
    "motor.inertia_kg_m2": Uncertain("motor.inertia_kg_m2", 1e-3, 2e-2, True, 0.2),
    "effects.friction_scale": Uncertain("effects.friction_scale", 0.2, 8.0, True, 0.5),
    "motor.kt_nm_per_a": Uncertain("motor.kt_nm_per_a", 0.6, 3.0, True, 0.1),
    "screw.lead_m": Uncertain("screw.lead_m", 4e-3, 6e-3, False, 0.01),
    "sensors.lvdt_gain": Uncertain("sensors.lvdt_gain", 0.8, 1.25, False, 0.02),
    "sensors.encoder_gain": Uncertain("sensors.encoder_gain", 0.8, 1.25, False, 0.02),
    "sensors.current_offset_a": Uncertain("sensors.current_offset_a", -2.0, 2.0, False, 0.2,
                                          relative=False),
}
DEFAULT = tuple(UNCERTAIN)
ALIASES = [("motor.kt_nm_per_a", "motor.inertia_kg_m2", "ratio kt / J"),
           ("screw.lead_m", "sensors.lvdt_gain", "product lead x LVDT gain")]


class PlantSet(Effect):
    """A generic effect setting the named plant parameters (calibration)."""
    name = "calibration"
    doc = "nominal model's uncertain parameters"

    def __init__(self, names: Sequence[str]) -> None:
        ps = []
        for n in names:
            u = UNCERTAIN[n]
            ps.append(Param(n, resolve(n).unit, u.lo, u.hi, resolve(n).doc, log=u.log))
        self.params = tuple(ps)   # type: ignore[misc]

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {p.name: float(base.get(p.name)) for p in self.params}

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        return dict(theta)

    def start_points(self, base: PlantParams) -> list[dict[str, float]]:
        return [self.nominal(base)]


def calibrate(trace: Trace, base: PlantParams | None = None,
              names: Sequence[str] = DEFAULT, model: str = "plant",
              encoder: str = "absolute") -> dict[str, Any]:
    """Fit `names` to the healthy `trace`; the calibration JSON (see module doc)."""
    if model != "plant":
        from bench.gap.models import check_model
        check_model(model)
    for n in names:
        if n not in UNCERTAIN:
            raise BenchError(f"cannot calibrate {n!r} (calibrated parameters: "
                             f"{', '.join(UNCERTAIN)})")
    base = base or PlantParams()
    p = build(trace.measured(), base, holdout_frac=0.3, encoder=encoder,
              purpose="calibration")
    eff = PlantSet(names)
    nom = eff.nominal(p.base)
    prior = {}
    for prm in eff.params:
        u = UNCERTAIN[prm.name]
        v = nom[prm.name]
        sd_val = u.tol * abs(v) if u.relative else u.tol
        # sd in [0, 1] coordinates at the nominal value
        sd_u = sd_val / max(prm.dvalue_du(prm.to_unit(min(max(v, prm.lo), prm.hi))), 1e-300)
        prior[prm.name] = (min(max(v, prm.lo), prm.hi), max(sd_u, 1e-6))
    f = fit(p, [eff], [nom], max_nfev=80, prior=prior)
    nominal_sim = p.info["nominal"]
    after = p.simulate([eff], f.theta)
    before_fit = p.energies(nominal_sim, 0, p.n_fit)
    after_fit = p.energies(after, 0, p.n_fit)
    before_ho = p.energies(nominal_sim, p.n_fit, p.n)
    after_ho = p.energies(after, p.n_fit, p.n)
    params = {k: float(v) for k, v in f.theta[0].items()}
    ci = {k: [float(a), float(b)] for k, (a, b) in f.ci95[0].items()}
    loaded = p.drive.load_n is not None and float(np.nanmax(np.abs(p.drive.load_n))) > 100.0
    how = ("mostly through their" if loaded else "only through their")
    why = (" (the logged load's holding current, F p / (2 pi eta tau kt), is a small "
           "addition)" if loaded else " on a log without force measurement")
    notes = [f"{a} and {b} act {how} {what}{why}: the log fixes the {what}; the prior "
             "tolerances split it" for a, b, what in ALIASES if a in names and b in names]
    return {
        "model": model,
        "fidelity": "fast mode (averaged PWM, massless balls)",
        "params": params,
        "ci95": ci,
        "nominal": {k: float(v) for k, v in nom.items()},
        "prior_sd": {n: (UNCERTAIN[n].tol if not UNCERTAIN[n].relative
                         else f"{UNCERTAIN[n].tol:.0%}") for n in names},
        "gap_before": {"fit_part": _norm(before_fit), "heldout_part": _norm(before_ho)},
        "gap_after": {"fit_part": _norm(after_fit), "heldout_part": _norm(after_ho)},
        "noise_sigma": p.noise_sigma,
        "samples": p.n, "fit_samples": p.n_fit,
        "notes": notes,
    }


def _norm(en: dict[str, float]) -> dict[str, float]:
    out = {s: float(math.sqrt(max(v, 0.0))) for s, v in en.items()}
    out["total"] = float(np.sqrt(np.mean(list(en.values()))))
    return out


__all__ = ["calibrate", "UNCERTAIN", "DEFAULT", "R"]
