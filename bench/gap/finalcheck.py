"""The final check of the gap diagnosis: physics no diagnosis change was tuned to
(`bench gap-bench --generator final-check`; docs/gap-results.md, "The final check").

`indie_plant` is the development generator: the diagnosis was changed while looking at
its results, so it is no longer independent of them. The final check keeps three things
away from development, fixed here before it was run once:

- physics the development runs never switched on (`PHYSICS`): a Coulomb friction that
  ripples along every screw turn (ball recirculation), a rod seal's Coulomb force on the
  nut (friction at the nut, where the independent actuator has none), and an anti-alias
  filter on the logged current sensor;
- randomised builds (`build`): three actuators whose motor constants, inertia, friction
  laws, contact stiffness, preload and nut mass are drawn from catalogue tolerances with
  fixed seeds, while the bench knows only the datasheet (`indiebench.datasheet_model` of
  the nominal actuator) and calibrates it on one healthy log of each;
- withheld effects at fixed sizes (`CASES`), the kinds the diagnosis' goals name.

Each actuator is calibrated on its own healthy log and judged against its own held-out
healthy log (`indiebench`'s procedure); the cases' noise seeds are fixed (`NOISE_SEEDS`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from bench.gap import indiebench as IB
from bench.gap.blind import Case, Truth, score, summarise
from bench.gap.calibrate import reference_of
from bench.gap.diagnose import Options, diagnose
from bench.runtime.workers import run_all
from indie_plant.params import IndieParams

PHYSICS = {"friction_ripple": 0.15, "seal_friction_n": 40.0, "current_filter_s": 3e-4}
"""The final check's physics (indie_plant I15-I17), on in every one of its logs."""
BUILD_SEEDS = (9101, 9102, 9103)
"""One randomised actuator per seed (the first final check: `build_seeds(9101)`)."""
NOISE_SEEDS = 40_000
"""Case j of actuator a has noise seed noise_base + 100 a + j (`noise_base`, NOISE_SEEDS
for the first final check); its calibration log + 90, its held-out healthy log + 91, the
floor's + 92..94."""
FRESH_SEED = 9301
"""The second final check's first build seed (`--build-seed 9301`), fixed before it ran:
builds 9301-9303, noise seeds 42000-42294, never run by any development or earlier
check."""
THIRD_SEED = 9501
"""The third final check's first build seed (`--build-seed 9501`), fixed before it ran,
after the pair selection's alias swap and the verdict's model-form interval term: builds
9501-9503, noise seeds 44000-44294, never run by any development or earlier check."""
FOURTH_SEED = 9701
"""The fourth final check's first build seed (`--build-seed 9701`), fixed before it ran,
after the pair rule's significance clause: builds 9701-9703, noise seeds 46000-46294,
never run by any development or earlier check."""
FIFTH_SEED = 9901
"""The fifth final check's first build seed (`--build-seed 9901`), fixed before it ran,
after the pair rule's floor clause: builds 9901-9903, noise seeds 48000-48294, never run
by any development or earlier check."""
SIXTH_SEED = 10101
"""The sixth final check's first build seed (`--build-seed 10101`), fixed before it ran,
with no change to the diagnosis since the fifth: a second measurement of the same
diagnosis on new builds 10101-10103 and noise seeds 50000-50294, never run by any
development or earlier check."""


def build_seeds(first: int = BUILD_SEEDS[0]) -> tuple[int, int, int]:
    """The three builds' seeds of the final check whose first build seed is `first`."""
    return first, first + 1, first + 2


def noise_base(first: int = BUILD_SEEDS[0]) -> int:
    """The noise seed of case 0 of actuator 0 for the check of first build seed `first`:
    NOISE_SEEDS for the first final check, 10 per build seed further for another (the
    three actuators' 300 seeds never overlap another check's)."""
    return NOISE_SEEDS + 10 * (first - BUILD_SEEDS[0])


LOWEST_BUILD_SEED = BUILD_SEEDS[0] - NOISE_SEEDS // 10
"""The lowest first build seed whose noise seeds are >= 0 (`noise_base` of it is 0)."""
NOISE_SEEDS_PER_CHECK = 300
"""Noise seeds one check draws from `noise_base` on: 100 per actuator, three actuators."""


def highest_build_seed(seed_max: int) -> int:
    """The highest first build seed whose build seeds and noise seeds are all <= seed_max
    (the largest seed the bench's generators are given)."""
    top = BUILD_SEEDS[0] + (seed_max - NOISE_SEEDS - NOISE_SEEDS_PER_CHECK + 1) // 10
    return min(top, seed_max - 2)


def build(seed: int) -> IndieParams:
    """A randomised actuator: the nominal one with every build parameter drawn from its
    catalogue tolerance (uniform; factors on the nominal), and `PHYSICS` on."""
    rng = np.random.default_rng(seed)
    n = IndieParams()

    def f(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    k = f(0.93, 1.07)
    return n.with_dict({
        **PHYSICS,
        "kt_nm_per_a": n.kt_nm_per_a * k, "ke_v_s_per_rad": n.ke_v_s_per_rad * k,
        "resistance_ohm": n.resistance_ohm * f(0.9, 1.1),
        "inertia_kg_m2": n.inertia_kg_m2 * f(0.85, 1.15),
        "coulomb_nm": n.coulomb_nm * f(0.6, 1.6),
        "static_ratio": f(1.15, 1.8),
        "stribeck_rad_s": n.stribeck_rad_s * f(0.5, 2.0),
        "viscous_nm_s_per_rad": n.viscous_nm_s_per_rad * f(0.5, 2.0),
        "screw_friction": n.screw_friction * f(0.7, 1.4),
        "bristle_nm_per_rad": n.bristle_nm_per_rad * f(0.5, 2.0),
        "hertz_n_per_m15": n.hertz_n_per_m15 * f(0.6, 1.6),
        "preload_n": n.preload_n * f(0.8, 1.2),
        "nut_mass_kg": n.nut_mass_kg * f(0.8, 1.2),
    })


def _cases(a: IndieParams) -> list[tuple[str, list[Truth]]]:
    """The withheld effects on actuator `a` (name, truths): two healthy logs, then one
    effect each and one pair, at fixed sizes."""
    def t(name: str, **plant: float) -> Truth:
        return Truth(name, plant=dict(plant))
    return [
        ("nominal", []), ("nominal", []),
        ("friction: every level x2.5", [t("friction", friction_scale=2.5, viscous_scale=2.5)]),
        ("friction: Coulomb and static x1.8", [t("friction", friction_scale=1.8)]),
        ("backlash 40 um", [t("backlash", backlash_m=40e-6)]),
        ("backlash 40 um + friction x2", [t("backlash", backlash_m=40e-6),
                                          t("friction", friction_scale=2.0,
                                            viscous_scale=2.0)]),
        ("preload lost to 40 %", [t("preload", preload_n=0.4 * a.preload_n)]),
        ("LVDT transport delay 3 ms, in the loop", [t("lvdt_delay", lvdt_delay_periods=3.0)]),
        ("LVDT and encoder delay 2 ms", [t("sensor_delay", sensor_delay_periods=2.0)]),
        ("LVDT gain 1.03", [t("lvdt_gain", lvdt_gain=1.03)]),
        ("encoder gain 0.97", [t("encoder_gain", encoder_gain=0.97)]),
        ("current offset 0.3 A (logged)", [t("current_offset", current_offset_a=0.3)]),
        ("lead +1 %", [t("lead", lead_m=a.lead_m * 1.01)]),
    ]


def truth_size(t: Truth, actuator: IndieParams) -> tuple[str, float, float] | None:
    """`indiebench.truth_size` on the built `actuator` (its free play from its own preload
    deflection); the lead and the preload relative to the datasheet's (the bench's model
    starts from it; the built preload is drawn around it)."""
    return IB.truth_size(t, actuator)


_STATE: dict[int, dict[str, Any]] = {}


def _init(states: dict[int, dict[str, Any]]) -> None:
    _STATE.update(states)


def run_case(item: tuple[int, Case], duration_s: float = IB.LOG_S) -> dict[str, Any]:
    """Generate, diagnose against actuator a's calibration (seeing only the log), score."""
    a, case = item
    st = _STATE[a]
    act = st["actuator"]
    log = IB.generate(case, True, duration_s, "ecu", act)
    t0 = time.perf_counter()
    res = diagnose(log, nominal=st["model"], options=Options(
        workers=1, reference=st["reference"], friction_split=IB.FRICTION_SPLIT))
    elapsed = time.perf_counter() - t0
    snr_each = {t.name: IB.floor_snr(Case(case.index, case.kind, [t], case.noise_seed),
                                     duration_s, st["ref"], "ecu", act) for t in case.truths}
    snr_all = IB.floor_snr(case, duration_s, st["ref"], "ecu", act) if case.truths else {}
    rec = score(case, res.json(), snr_each, snr_all, elapsed,
                sizes=partial(truth_size, actuator=act))
    rec["actuator"] = a
    rec["case_name"] = st["names"][case.index]
    rec["truth_values"] = {t.name: t.plant for t in case.truths}
    return rec


def calibrate_actuator(a: int, duration_s: float = IB.LOG_S,
                       first: int = BUILD_SEEDS[0]) -> dict[str, Any]:
    """Actuator a's build, its datasheet model calibrated on its healthy log, the held-out
    healthy level the cases are judged against, and the generator's floor (`first`: the
    check's first build seed)."""
    from bench.gap.calibrate import calibrate, default_names
    act = build(build_seeds(first)[a])
    s0 = noise_base(first) + 100 * a
    healthy = IB.generate(Case(-1, "nominal", [], s0 + 90), True, duration_s, "ecu", act)
    base = IB.datasheet_model()
    cal = calibrate(healthy, base, default_names(healthy))
    model = base.with_dict(cal["params"])
    held = IB.generate(Case(-1, "nominal", [], s0 + 91), True, duration_s, "ecu", act)
    from bench.gap.calibrate import heldout_significance
    sig = heldout_significance(cal, base, [held], [f"final check {a}, noise seed {s0 + 91}"])
    return {"actuator": act, "model": model, "calibration": cal,
            "reference": reference_of(cal | {"heldout_significance": sig},
                                      f"final-check-{a}") | {"healthy_logs": [held]},
            "ref": IB.reference(duration_s, s0 + 92, "ecu", act)}


def run(workers: int = 2, duration_s: float = IB.LOG_S, progress: bool = True,
        on_result: Callable[[dict[str, Any]], None] | None = None,
        scheduler: str | None = None, first: int = BUILD_SEEDS[0]) -> dict[str, Any]:
    """Calibrate the three actuators, then diagnose every case of each (`first`: the
    first build seed, `build_seeds`; 9101 the first final check, FRESH_SEED the second,
    THIRD_SEED the third, FOURTH_SEED the fourth, FIFTH_SEED the fifth, SIXTH_SEED
    the sixth)."""
    t0 = time.perf_counter()
    states, items = {}, []
    seeds, base = build_seeds(first), noise_base(first)
    for a in range(len(seeds)):
        st = calibrate_actuator(a, duration_s, first)
        cases = _cases(st["actuator"])
        st["names"] = [name for name, _ in cases]
        states[a] = st
        for j, (_name, truths) in enumerate(cases):
            kind = "nominal" if not truths else ("pair" if len(truths) > 1 else "single")
            items.append((a, Case(j, kind, truths, base + 100 * a + j)))
    t_cal = time.perf_counter() - t0
    job = partial(run_case, duration_s=duration_s)
    results = run_all(job, items, workers, progress, desc="gap-bench (final check)",
                      unit="case", initializer=_init, initargs=(states,),
                      on_result=on_result, leave=True, scheduler=scheduler)
    return {"generator": "final-check", "controller": "ecu", "seed": first,
            "cases": len(items), "fidelity": "independent physics with the final check's "
            "physics on, randomised builds", "log_s": duration_s, "workers": workers,
            "physics": PHYSICS, "build_seeds": seeds, "wall_s": time.perf_counter() - t0,
            "calibration_wall_s": t_cal,
            "actuators": [{"build": {k: v for k, v in dataclasses.asdict(st["actuator"]).items()
                                     if v != getattr(IB.NOMINAL, k)},
                           "calibration": {k: st["calibration"].get(k) for k in
                                           ("params", "ci95", "nominal", "prior_distance_sd",
                                            "at_bound", "gap_after", "notes")}}
                          for st in states.values()],
            "summary": summarise(results), "results": results}
