"""Calibration of the nominal model to a healthy log (`bench calibrate`).

A different actuator has different parameters from the thesis' tables; diagnosing it
against the thesis would report its build tolerances as a gap. Calibration fits the
nominal model's uncertain parameters to a healthy log of that actuator, so later logs
are diagnosed against its own baseline (`bench gap --nominal CALIBRATION.json`).

The fit is the diagnosis' closed-loop least squares with all uncertain parameters at
once and a Gaussian prior on each (its tolerance, below) that keeps aliased parameters
well posed: on a log without a force measurement, torque constant and inertia act
through their ratio, and screw lead and LVDT gain through their product, so the data fix
the ratio/product and the prior shares it out. The output states this. Every parameter
is in the one least squares, the viscous coefficient and the contact stiffness too (they
were once set by a grid profile, because the model's encoder counts hid their gradient;
the fits' encoder is continuous now, `bench.gap.problem.continuous`): fitted one after the
other, the least squares took the lead x LVDT-gain alias for a softer nut (the controller
holds the LVDT reading, so the encoder reads set-point + gain x deflection) and moved the
independent actuator's 4 mm lead to 3.34 mm with an LVDT gain of 1.197, 18 and 9 prior sd
off; together, the stiffness takes the compliance and the lead stays within 0.1 sd.

The controller (`controller`, CONTROLLERS): by default the log is re-simulated under
the bench's ECU (`bench-ecu`: the log was run under it, as over the bus). For a log run
under a controller the bench does not know, either its gains are identified
(`fitted-cascade`: a generic position/speed cascade, `bench.gap.cascade`, fitted in
closed loop by `fit_cascade` before the plant's parameters, then refitted with them), or
the log is re-simulated without one (`measured-current`: the logged current drives the
plant, the mechanics re-started from the measured encoder angle every
`bench.gap.resim.RESTART_S`). The output says which (`controller`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench import BenchError
from bench.gap import resim as R
from bench.gap.candidate import bound_scale
from bench.gap.cascade import Cascade
from bench.gap.effects import Effect, Param
from bench.gap.fit import fit
from bench.gap.inputs import Calibration
from bench.gap.problem import Problem, build, with_rate
from bench.signals.trace import Trace
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
    follows_model: bool = False
    """lo and hi are a range around the thesis' actuator's value, scaled to the start
    model's value (`bench.gap.candidate.bound_scale`), so another actuator's lead or rotor
    lies where the thesis' lies in it: neither clipped into the thesis' range nor on one of
    its edges (a 4 mm lead on the 4-6 mm range could only grow)."""


UNCERTAIN: dict[str, Uncertain] = {
    "motor.inertia_kg_m2": Uncertain("motor.inertia_kg_m2", 1e-3, 2e-2, True, 0.2, follows_model=True),
    "effects.friction_scale": Uncertain("effects.friction_scale", 0.2, 8.0, True, 0.5),
    "motor.kt_nm_per_a": Uncertain("motor.kt_nm_per_a", 0.6, 3.0, True, 0.1, follows_model=True),
    "screw.lead_m": Uncertain("screw.lead_m", 4e-3, 6e-3, False, 0.01, follows_model=True),
    "sensors.lvdt_gain": Uncertain("sensors.lvdt_gain", 0.8, 1.25, False, 0.02),
    "sensors.encoder_gain": Uncertain("sensors.encoder_gain", 0.8, 1.25, False, 0.02),
    "sensors.current_offset_a": Uncertain("sensors.current_offset_a", -2.0, 2.0, False, 0.2,
                                          relative=False),
}
DEFAULT = tuple(UNCERTAIN)
# the nut's contact stiffness k* (eq. 5.21): a catalogue gives the preloaded nut's axial
# rigidity only roughly (1 sd 50 %); not in DEFAULT: identified only under a logged load
UNCERTAIN["screw.contact_stiffness_n_per_m"] = Uncertain(
    "screw.contact_stiffness_n_per_m", 1e7, 1e9, True, 0.5)
# viscous friction (eq. 5.13): the thesis' table value (5.8e-8 N m s/rad) is far below
# a catalogue motor's; absolute 1 sd 1e-3 N m s/rad
UNCERTAIN["motor.viscous_friction_nm_s"] = Uncertain(
    "motor.viscous_friction_nm_s", 0.0, 0.01, False, 1e-3, relative=False)
# the screw's reaction lever r of C_V (eq. 5.10): the torque an axial force needs, per N,
# is its lever times tan(alpha) / g. The thesis' r_m - r_b cos(beta) gives 0.91 of the
# work-consistent p / 2 pi; another actuator's screw need not share it, and the current
# that holds the logged load shows it. Identified under a logged load only
# (`default_names`); 1 sd 15 %.
UNCERTAIN["screw.reaction_lever_m"] = Uncertain("screw.reaction_lever_m", 1e-3, 0.1, True,
                                                0.15, follows_model=True)
LOADED_N = 100.0
"""A log whose load cell reads more than this (N) carries a load that identifies the
contact stiffness (the encoder-LVDT deflection follows it); see `default_names`."""


def default_names(trace: Trace) -> tuple[str, ...]:
    """The parameters a healthy `trace` identifies (`bench calibrate`'s default): DEFAULT,
    the viscous friction (the torque that grows with speed, beside the Coulomb level of
    friction_scale) and, when its load cell shows a load (|F| > LOADED_N), the contact
    stiffness (the deflection between the encoder's travel and the LVDT follows the logged
    force; without it the contact force is the nut's friction of nearly constant
    magnitude and the stiffness aliases with backlash) and the screw's reaction lever (the
    current that holds the logged force)."""
    out = DEFAULT + ("motor.viscous_friction_nm_s",)
    if "load_force_n" in trace.columns:
        f = np.asarray(trace["load_force_n"], float)
        if np.isfinite(f).any() and float(np.nanmax(np.abs(f))) > LOADED_N:
            out += ("screw.contact_stiffness_n_per_m", "screw.reaction_lever_m")
    return out


def value_of(base: PlantParams, name: str) -> float:
    """The model's value of calibrated parameter `name` (the reaction lever's NaN default
    resolved to the lever it stands for, `ScrewParams.lever_m`)."""
    if name == "screw.reaction_lever_m":
        return float(base.screw.lever_m)
    return float(base.get(name))
ALIASES = [("motor.kt_nm_per_a", "motor.inertia_kg_m2", "ratio kt / J"),
           ("screw.lead_m", "sensors.lvdt_gain", "product lead x LVDT gain")]


class PlantSet(Effect):
    """A generic effect setting the named plant parameters (calibration)."""
    name = "calibration"
    doc = "nominal model's uncertain parameters"

    def __init__(self, names: Sequence[str], base: PlantParams | None = None) -> None:
        ps = []
        for n in names:
            u = UNCERTAIN[n]
            prm = Param(n, resolve(n).unit, u.lo, u.hi, resolve(n).doc, log=u.log)
            k = (value_of(base, n) / value_of(PlantParams(), n)
                 if n == "screw.reaction_lever_m" else bound_scale(base, n)) \
                if u.follows_model and base is not None else 1.0
            ps.append(prm.scaled(k) if k != 1.0 else prm)
        self.params = tuple(ps)   # type: ignore[misc]

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {p.name: value_of(base, p.name) for p in self.params}

    def plant_overrides(self, theta: Mapping[str, float], base: PlantParams) -> dict[str, Any]:
        return dict(theta)

    def start_points(self, base: PlantParams) -> list[dict[str, float]]:
        return [self.nominal(base)]


def calibrate(trace: Trace, base: PlantParams | None = None,
              names: Sequence[str] = DEFAULT, model: str = "plant",
              encoder: str = "absolute", controller: str = "bench-ecu",
              cascade: Cascade | None = None) -> dict[str, Any]:
    """Fit `names` to the healthy `trace`; the calibration JSON (see module doc).
    `cascade`: with controller fitted-cascade, a known cascade (no controller fit)."""
    if controller not in CONTROLLERS:
        raise BenchError(f"controller must be one of {', '.join(CONTROLLERS)}, not "
                         f"{controller!r}")
    base = base or PlantParams()
    if controller == "fitted-cascade" and cascade is None:
        return calibrate_with_cascade(trace, base, names, encoder)
    if model != "plant":
        from bench.gap.models import check_model
        check_model(model)
    for n in names:
        if n not in UNCERTAIN:
            raise BenchError(f"cannot calibrate {n!r} (calibrated parameters: "
                             f"{', '.join(UNCERTAIN)})")
    p = build(trace.measured(), base, holdout_frac=0.3, encoder=encoder,
              purpose="calibration", resim=RESIM[controller], cascade=cascade)
    eff = PlantSet(names, p.base)
    nom = eff.nominal(p.base)
    nominal_sim = p.info["nominal"]
    f = fit(p, [eff], [nom], max_nfev=80, prior=_prior(eff, nom))
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
    distance = prior_distance(params, nom)
    edge = f.bounded()
    notes += [f"{k} = {params[k]:.4g} is {z:+.1f} prior sd from the description's "
              f"{nom[k]:.4g}: the healthy log asks for more than its tolerance (a wrong "
              "description, or a difference of form this parameter absorbs; a later fault "
              "may then need it moved back)" for k, z in distance.items() if abs(z) > FAR_SD]
    notes += [f"{k} ended on its bound: the log asks for more than the range allows"
              for k in edge]
    return Calibration("plant", {
        "model": model,
        "fidelity": "fast mode (averaged PWM, massless balls)",
        "controller": {"method": controller, "doc": CONTROLLERS[controller],
                       **({"cascade": cascade.describe()} if cascade else {})},
        "params": params,
        "ci95": ci,
        "nominal": {k: float(v) for k, v in nom.items()},
        "prior_sd": {n: (UNCERTAIN[n].tol if not UNCERTAIN[n].relative
                         else f"{UNCERTAIN[n].tol:.0%}") for n in names},
        "prior_distance_sd": distance,
        "at_bound": edge,
        "gap_before": {"fit_part": _norm(before_fit), "heldout_part": _norm(before_ho)},
        "gap_after": {"fit_part": _norm(after_fit), "heldout_part": _norm(after_ho)},
        "noise_sigma": p.noise_sigma,
        "samples": p.n, "fit_samples": p.n_fit,
        "notes": notes,
    }).to_dict()


FAR_SD = 2.0
"""A calibrated value further than this many prior standard deviations from the
description's is reported (`notes`): the healthy log moved it beyond its tolerance."""


def prior_distance(params: Mapping[str, float], nom: Mapping[str, float]) -> dict[str, float]:
    """Each calibrated value's distance from the description's value in prior standard
    deviations (its tolerance, `UNCERTAIN`; in ln for a relative one)."""
    out = {}
    for k, v in params.items():
        u, v0 = UNCERTAIN.get(k), nom.get(k)
        if u is None or v0 is None:
            continue
        if u.relative and v > 0 and v0 > 0:
            out[k] = math.log(v / v0) / u.tol
        else:
            sd = u.tol * abs(v0) if u.relative else u.tol
            out[k] = (v - v0) / sd if sd > 0 else 0.0
    return out


def _prior(eff: PlantSet, nom: Mapping[str, float]) -> dict[str, tuple[float, float]]:
    """The fit's Gaussian prior per parameter: its nominal value and tolerance (1 sd, in
    the fit's [0, 1] coordinates at the nominal value)."""
    prior = {}
    for prm in eff.params:
        u = UNCERTAIN[prm.name]
        v = nom[prm.name]
        sd_val = u.tol * abs(v) if u.relative else u.tol
        sd_u = sd_val / max(prm.dvalue_du(prm.to_unit(min(max(v, prm.lo), prm.hi))), 1e-300)
        prior[prm.name] = (min(max(v, prm.lo), prm.hi), max(sd_u, 1e-6))
    return prior


CONTROLLERS = {
    "bench-ecu": "the bench's ECU (its structure and gains) closes the loops in the "
                 "re-simulation, as over the bus",
    "fitted-cascade": "the controller's gains identified: a generic cascade (position P/PI "
                      "on the LVDT or the encoder, speed PI, speed and current limits, "
                      "sample time in whole SYNC periods) fitted in closed loop "
                      "(bench.gap.cascade)",
    "measured-current": "no controller identified: the logged current drives the plant "
                        "(the drive tracks it), the mechanics re-started from the measured "
                        f"encoder angle and speed every {R.RESTART_S:g} s; the current is "
                        "an input, its residual only the drive's tracking",
}
"""What the calibration does about the controller (`calibrate(controller=...)`)."""
RESIM = {"bench-ecu": "closed-loop", "fitted-cascade": "closed-loop",
         "measured-current": "measured-current"}


def resim_of(controller: dict[str, Any]) -> dict[str, Any]:
    """`bench.gap.problem.build`'s keywords (resim, cascade) that re-simulate a log as a
    calibration's `controller` entry says."""
    c = controller.get("cascade")
    return {"resim": RESIM[controller["method"]],
            "cascade": None if c is None else Cascade.from_dict(c)}


def _norm(en: dict[str, float]) -> dict[str, float]:
    out = {s: float(math.sqrt(max(v, 0.0))) for s, v in en.items()}
    out["total"] = float(np.sqrt(np.mean(list(en.values()))))
    return out


__all__ = ["calibrate", "UNCERTAIN", "DEFAULT", "R", "heldout_significance"]

STATISTIC = ("smoothed residual energy / the log's noise floor of the calibrated model's "
             "re-simulation (the significance statistic of `bench gap`), per signal")


def heldout_significance(cal: dict[str, Any], base: PlantParams, holdouts: Sequence[Trace],
                         names: Sequence[str], encoder: str = "absolute",
                         model: str = "plant") -> dict[str, Any]:
    """The calibration's `heldout_significance` entry: the significance statistic the
    calibrated model (`base` with `cal`'s params, re-simulated as `cal["controller"]`
    says) leaves on each held-out healthy log (`names`: where they came from; never a log
    the calibration was fitted on), the largest per signal, and its margin
    (`bench.gap.diagnose.heldout_level`). Without held-out logs: the level is unknown and
    `bench gap --nominal` applies the default threshold."""
    from bench.gap.diagnose import heldout_level
    from bench.gap.problem import fill_gaps
    if not holdouts:
        return {"known": False, "logs": [], "level": None, "margin": None,
                "statistic": STATISTIC,
                "note": "no held-out healthy log (--holdout): level unknown, the default "
                        "significance threshold applies"}
    from bench.gap.alias import healthy_load_ratio
    modelled = base.with_dict(cal["params"])
    each, ratios = [], []
    for tr in holdouts:
        p = build(fill_gaps(tr.measured(), "held-out log"), modelled, 0.5, encoder=encoder,
                  purpose="held-out log", model=model, **resim_of(cal["controller"]))
        each.append(heldout_level(p))
        ratios.append(healthy_load_ratio(p))
    level = {s: max(e["level"][s] for e in each) for s in R.SIGNALS}
    margin = {s: max(e["margin"][s] for e in each) for s in R.SIGNALS}
    energy = {s: max(e["energy"][s] for e in each) for s in R.SIGNALS}
    return {"known": True, "logs": list(names), "level": level, "margin": margin,
            "energy": energy,
            "load_current_ratio": (float(np.mean([r for r in ratios if r is not None]))
                                   if ratios and None not in ratios else None),
            "per_log": [e["level"] for e in each], "model": model, "encoder": encoder,
            "statistic": STATISTIC,
            "rule": "bench gap --nominal: significant only where the log exceeds the larger "
                    "of the default threshold and level x margin"}


def reference_of(cal: dict[str, Any], name: str, model: str | None = None,
                 encoder: str | None = None) -> dict[str, Any]:
    """What `bench.gap.diagnose.Options.reference` takes from a calibration JSON `cal`
    (written by `calibrate` + `heldout_significance`; an older one has no level). A level
    measured with another model or encoder reference than the diagnosis' does not apply
    (unknown)."""
    hs = cal.get("heldout_significance") or {}
    known = bool(hs.get("known")) and all(
        want is None or hs.get(key, want) == want
        for key, want in (("model", model), ("encoder", encoder)))
    for key in ("level", "margin", "energy"):      # numbers per signal, or absent
        v = hs.get(key)
        if known and v is not None and not (isinstance(v, dict) and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                for x in v.values())):
            raise BenchError(f"{name}: heldout_significance.{key} must map each signal to a "
                             f"finite number, not {v!r}"[:200])
    return {"name": name, "level": hs.get("level") if known else None,
            "margin": hs.get("margin"), "logs": hs.get("logs", []),
            "energy": hs.get("energy") if known else None,
            "load_current_ratio": hs.get("load_current_ratio") if known else None,
            "paths": [str(x) for x in hs.get("paths") or []] if known else []}



# --- an unknown controller: a generic cascade fitted in closed loop ---------------------
CASCADE_SOURCES = ("lvdt", "encoder")
CASCADE_EVERY = (1, 2, 4)
"""The cascade structures tried (position sensor x sample time in SYNC periods); the one
whose fitted law leaves the smallest residual on the log's held-out part is kept."""
CASCADE_NFEV = 40
GRID = (0.1, 0.3, 1.0, 3.0, 10.0)
GRID_STARTS = 3


def initial_cascade(base: PlantParams, trace: Trace, source: str, every: int) -> Cascade:
    """A start for the fit from the model and the log: 6 Hz position bandwidth with a
    0.1 Hz integral zero, a 30 Hz speed crossover on the model's inertia at the motor
    (2 pi 30 J / kt) with its zero at 1/8 of it, the logged peak speed + 5 % as speed
    limit, the model's current limit."""
    from plant_rt.model import equivalent_inertia
    kpp = 2.0 * math.pi * 6.0 / R.angle_to_travel(base)
    j_motor = equivalent_inertia(base) * base.reducer.ratio ** 2
    kps = 2.0 * math.pi * 30.0 * j_motor / base.motor.kt_nm_per_a
    wmax = 1.05 * float(np.nanmax(np.abs(np.asarray(trace["motor_speed_rad_s"], float))))
    return Cascade(source, kpp, kpp * 2.0 * math.pi * 0.1, kps, kps * 2.0 * math.pi * 30 / 8,
                   max(wmax, 1.0), base.motor.current_max_a, every)


def _cascade_of(z: np.ndarray, c0: Cascade) -> Cascade:
    """z = ln of (kp_pos, position zero Hz, kp_spd, speed zero Hz, speed limit)."""
    kpp, fp, kps, fs, wl = np.exp(z)
    return Cascade(c0.source, kpp, kpp * 2 * math.pi * fp, kps, kps * 2 * math.pi * fs, wl,
                   c0.current_limit_a, c0.every_periods)


def fit_cascade(p: Problem, c0: Cascade, max_nfev: int = CASCADE_NFEV
                ) -> tuple[Cascade, float, float]:
    """The gains and speed limit of `c0`'s structure fitted to the log of `p` (samples
    [0, n_fit)) by closed-loop least squares on the normalised residuals; returns the
    fitted cascade and its gap excess on the fit and the held-out part."""
    from dataclasses import replace

    from scipy.optimize import least_squares
    drive0 = p.drive
    z0 = np.log([c0.kp_pos, c0.ki_pos / c0.kp_pos / (2 * math.pi), c0.kp_spd,
                 c0.ki_spd / c0.kp_spd / (2 * math.pi), c0.speed_limit_rad_s])
    lo = z0 + np.log([0.05, 0.01, 0.05, 0.02, 0.5])
    hi = z0 + np.log([20.0, 100.0, 20.0, 20.0, 3.0])

    def sim(z: np.ndarray) -> dict[str, np.ndarray]:
        p.drive = replace(drive0, cascade=_cascade_of(z, c0))
        return p.simulate()

    try:
        sol = least_squares(lambda z: p.residual(sim(z), 0, p.n_fit), z0, bounds=(lo, hi),
                            diff_step=1e-3, max_nfev=max_nfev, x_scale=1.0)
        best = sim(sol.x)
        out = _cascade_of(sol.x, c0)
    finally:
        p.drive = drive0
    return out, p.excess(best, 0, p.n_fit), p.excess(best, p.n_fit, p.n)


def fit_cascade_to_demand(trace: Trace, c0: Cascade, travel_per_rad: float,
                          n_fit: int) -> tuple[Cascade, float, float]:
    """The gains and speed limit of `c0`'s structure fitted so that the law, fed the
    logged set-points and sensor samples (`bench.gap.cascade.replay`), gives the logged
    current demand (samples [0, n_fit)); returns the cascade and the RMS demand error
    (A) on the fit and the held-out part. The controller alone, no plant model."""
    from scipy.optimize import least_squares

    from bench.gap.cascade import logged_inputs, replay_one_step
    cols = {c: np.asarray(trace[c], float) for c in trace.columns}
    ref, meas = logged_inputs(cols)
    dem = np.nan_to_num(cols["current_demand_a"])
    dt = trace.dt
    z0 = np.log([c0.kp_pos, c0.ki_pos / c0.kp_pos / (2 * math.pi), c0.kp_spd,
                 c0.ki_spd / c0.kp_spd / (2 * math.pi), c0.speed_limit_rad_s])
    lo = z0 + np.log([0.01, 0.01, 0.01, 0.01, 0.3])
    hi = z0 + np.log([100.0, 200.0, 100.0, 100.0, 5.0])

    def law(z: np.ndarray) -> np.ndarray:
        return replay_one_step(_cascade_of(z, c0).vector(dt, travel_per_rad), ref, meas, dem)

    def res(z: np.ndarray) -> np.ndarray:
        return law(z)[:n_fit] - dem[:n_fit]

    # an integrating law replayed open loop drifts far from wrong gains: start the local
    # fit from the best points of a coarse grid (x 1/10..10 around the start)
    grid = [z0 + np.log([a, b, c, d, 1.0]) for a in GRID for b in GRID for c in GRID
            for d in GRID]
    costs = [float(np.mean(res(np.clip(z, lo, hi)) ** 2)) for z in grid]
    best = None
    for i in np.argsort(costs)[:GRID_STARTS]:
        sol = least_squares(res, np.clip(grid[i], lo, hi), bounds=(lo, hi), diff_step=1e-4,
                            max_nfev=200)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    sol = best
    r = law(sol.x) - dem
    return (_cascade_of(sol.x, c0), float(np.sqrt(np.mean(r[:n_fit] ** 2))),
            float(np.sqrt(np.mean(r[n_fit:] ** 2))))


def identify_cascade(trace: Trace, base: PlantParams, encoder: str = "absolute"
                     ) -> tuple[Cascade, list[dict[str, Any]], bool]:
    """Every structure of CASCADE_SOURCES x CASCADE_EVERY fitted on the healthy `trace`
    (samples [0, 70 %)) and the one with the smallest error on the rest kept; returns it,
    the table of all and whether the fit was to the logged demand. With a logged current
    demand the law alone is fitted to it (`fit_cascade_to_demand`: error in A), else in
    closed loop with the model `base` (`fit_cascade`: the gap excess)."""
    tried: list[dict[str, Any]] = []
    has_demand = ("current_demand_a" in trace
                  and float(np.isfinite(np.asarray(trace["current_demand_a"], float)).mean())
                  > 0.9)
    n_fit = int(round(0.7 * len(trace)))
    for src in CASCADE_SOURCES:
        for every in CASCADE_EVERY:
            c0 = initial_cascade(with_rate(base, trace.dt), trace, src, every)
            if has_demand:
                c, e_fit, e_ho = fit_cascade_to_demand(trace, c0, R.angle_to_travel(base),
                                                       n_fit)
                what = "rms_demand_error_a"
            else:
                p = build(trace.measured(), base, holdout_frac=0.3, encoder=encoder,
                          purpose="calibration", cascade=c0, bootstrap=2)
                c, e_fit, e_ho = fit_cascade(p, c0)
                what = "excess"
            tried.append({"source": src, "every_periods": every, "fitted_to": what,
                          "fit_part": e_fit, "heldout_part": e_ho, "cascade": c})
    best = min(tried, key=lambda d: d["heldout_part"])
    return (best["cascade"], [{k: v for k, v in d.items() if k != "cascade"} for d in tried],
            has_demand)


def calibrate_with_cascade(trace: Trace, base: PlantParams, names: Sequence[str],
                           encoder: str) -> dict[str, Any]:
    """controller fitted-cascade: the cascade identified (`identify_cascade`), then the
    plant's parameters calibrated under it; a cascade fitted in closed loop with the
    datasheet model is refitted with the calibrated plant and the plant calibrated once
    more (module doc)."""
    c, tried, to_demand = identify_cascade(trace, base, encoder)
    cal = calibrate(trace, base, names, encoder=encoder, controller="fitted-cascade",
                    cascade=c)
    if not to_demand:
        model = base.with_dict(cal["params"])
        p = build(trace.measured(), model, holdout_frac=0.3, encoder=encoder,
                  purpose="calibration", cascade=c, bootstrap=2)
        c, _, _ = fit_cascade(p, c)
        cal = calibrate(trace, base, names, encoder=encoder, controller="fitted-cascade",
                        cascade=c)
    cal["controller"]["fitted_to"] = ("the logged current demand (the law fed the logged "
                                      "set-points and sensor samples)" if to_demand else
                                      "the logged signals, in closed loop with the model")
    cal["controller"]["structures_tried"] = tried
    return cal
