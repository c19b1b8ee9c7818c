"""Blind check of the gap diagnosis on logs from an independent actuator
(`bench gap-bench --generator independent`).

The logs come from `indie_plant`, physics written apart from `plant_rt` on purpose
(LuGre friction, a Hertzian preloaded double nut, cogging and torque ripple, ADC,
encoder and LVDT quantisation; docs/independent-plant.md) and another actuator (1:3,
4 mm lead, a lighter motor). The bench does not know that model: it starts from the
actuator's datasheet values (`datasheet_model`: what a vendor gives, put into the
bench's own model family) and first calibrates them on healthy logs of the actuator
(`bench.gap.calibrate`, on seeds the judged cases never use), then diagnoses every case
against the calibrated model.

The controller: by default the cases run under the bench's ECU (its structure and gains,
`indie_plant.controller.Cascade.like_bench_ecu`), as `bench run gap-excitation` against
`python -m indie_plant` over the bus gives; `controller="own"` runs the actuator's own
PI + PI cascade at 2 ms, which the bench does not know: its calibration and goal 4 then
identify it (`RESIM`: a fitted generic cascade, or the measured current driving the
model), and the blind diagnoses re-simulate under what it identified.

Cases: 30 % nominal (noise only), 70 % one effect of `POOL` at a random magnitude, the
effect implemented in the independent physics (not by the library). "Above the noise
floor" as in `bench.gap.blind`: the noise-free log with the effect against the noise-free
nominal log over the RMS difference of two noisy nominal logs / sqrt 2.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from bench.gap.blind import Case, Truth, score, summarise
from bench.gap.calibrate import calibrate, default_names, heldout_significance, reference_of
from bench.gap.diagnose import Options, diagnose
from bench.gap.problem import under_controller
from bench.profiles.maneuvers import LOAD_HZ, excitation
from bench.runtime.workers import run_all
from bench.signals.trace import Trace
from bench.sim.control import ControllerParams
from indie_plant.controller import Cascade
from indie_plant.generate import simulate as indie_simulate
from indie_plant.params import IndieParams
from plant_rt.contacts import helix_rad, normal_to_axis
from plant_rt.params import PlantParams

LOG_S = 10.0
LOAD_N = 2000.0
NOMINAL = IndieParams()
CALIBRATION_SEED_OFFSET = 100_003     # healthy calibration log: seed + this
HELDOUT_SEED_OFFSET = 100_004         # healthy held-out log (goal 4): seed + this
SNR_SIGNALS = ("current_a", "motor_speed_rad_s", "position_m", "motor_angle_rad")


SCREW_DIAMETER_M = 0.016
"""The independent actuator's screw diameter (its datasheet: a 16 mm screw, 4 mm lead)."""
PRELOAD_DRAG_K = 0.05
"""The catalogue's preload drag torque of a preloaded nut, T_p = K (tan lambda)^-0.5
F_pr p / 2 pi with the lead angle tan lambda = p / (pi d) (THK's ball screw catalogue,
'preload dynamic torque', K = 0.05; a formula from memory, the page was not at hand)."""


def catalogue_preload_drag_nm(actuator: IndieParams = NOMINAL) -> float:
    """The preloaded nut's no-load drag torque at the screw (N m) by the catalogue
    formula (`PRELOAD_DRAG_K`) from the datasheet's preload, lead and screw diameter."""
    tan_lead = actuator.lead_m / (math.pi * SCREW_DIAMETER_M)
    return PRELOAD_DRAG_K / math.sqrt(tan_lead) * actuator.preload_n * actuator.lead_m \
        / (2.0 * math.pi)


def rolling_friction_for_drag(params: PlantParams, drag_nm: float) -> float:
    """The rolling friction coefficient f_v that gives `params`' model the no-load drag
    `drag_nm` (N m, at the screw) at its preload F_pr: each nut carries F_pr, Z balls
    at F_pr / (Z g) along the normal, so the screw's rolling term (eq. 5.13, third term:
    Z f_v sum|P| cos(alpha) r) and the nuts' (eq. 5.31: f_v Z |P| each, at p / 2 pi per
    screw radian) give f_v (2 F_pr / g) (cos(alpha) r + p / 2 pi)."""
    s = params.screw
    g = normal_to_axis(params)
    lever = math.cos(helix_rad(s)) * s.lever_m + s.lead_m / (2 * math.pi)
    return drag_nm * g / (2.0 * params.effects.preload_n * lever)


PRELOAD_LAWS = ("none", "hertz", "hertz-fv", "hertz-drag")
"""How the datasheet model declares its preloaded double nut (docs/gap.md, "Decisions"): none (before indie6); hertz (the default): the Hertzian preload
law at the datasheet preload, the drag left to the thesis' rolling terms; hertz-fv and
hertz-drag add the catalogue's preload drag through the rolling friction f_v or as a
screw torque per N of preload (both rejected on the healthy logs under the bench's ECU)."""


def datasheet_model(actuator: IndieParams = NOMINAL, preload_law: str = "hertz"
                    ) -> PlantParams:
    """The bench's model of the independent actuator from its datasheet: ratio, lead,
    motor constants, rotor and screw inertias, nut mass, preload, supply and limits, the
    drive's current PI (its zero on the winding's own pole), its
    spacer-preloaded nut (a backlash first eats the preload), and
    how its drive computes the speed (the count difference over `speed_window` SYNC
    periods), the LVDT conditioner's lag (first order, `lvdt_tau_s`) and where its current
    is logged (a channel of its own, out of the drive's loop). The bench's
    friction laws and contact model stay its own (the thesis' tables): friction, the
    contact stiffness (under the logged load) and the rest are what calibration is for.

    `preload_law` (`PRELOAD_LAWS`): the nut is a preloaded double nut
    with Hertzian contacts (its datasheet), so the model declares the Hertzian preload
    law at the datasheet preload (`screw.hertz_reference_preload_n`; "hertz", the
    default) and, optionally, the preload's drag by the catalogue formula
    (`catalogue_preload_drag_nm`): as a screw torque per N of preload
    (`screw.preload_drag_nm_per_n`, "hertz-drag") or through the rolling friction f_v of
    eq. 5.13 and 5.31 ("hertz-fv"); "none" gives the model before indie6."""
    n = actuator
    model = PlantParams().with_dict({
        "motor.kt_nm_per_a": n.kt_nm_per_a, "motor.ke_v_s_per_rad": n.ke_v_s_per_rad,
        "motor.resistance_ohm": n.resistance_ohm, "motor.inductance_h": n.inductance_h,
        "motor.inertia_kg_m2": 2.4e-3,            # rotor alone on the datasheet
        "reducer.inertia_kg_m2": 2e-5, "screw.screw_inertia_kg_m2": 5e-5,
        "motor.current_max_a": n.current_limit_a, "motor.supply_voltage_v": n.supply_v,
        "reducer.ratio": n.ratio, "screw.lead_m": n.lead_m,
        # the thesis' helix angle is kept at this lead (the nominal lever, calibrated
        # through kt and friction); a change of lead from it moves the helix (tan ~ p)
        "screw.helix_reference_lead_m": n.lead_m,
        "screw.nut_mass_kg": n.nut_mass_kg, "effects.preload_n": n.preload_n,
        "drive.current_kp_v_per_a": 2 * math.pi * n.current_bw_hz * n.inductance_h,
        "drive.current_ki_v_per_as": 2 * math.pi * n.current_bw_hz * n.resistance_ohm,
        # its drive puts the current PI's zero on the winding's own pole (I2, ki from the
        # winding's R): a resistance that has risen is still cancelled
        "drive.current_pi_follows_winding": True,
        # its nut: a double nut preloaded by a spacer (an interference), so a wear clearance
        # eats the preload first and only then opens lost motion (I8)
        "screw.preload_by_interference": True,
        "sensors.encoder_counts_per_rev": n.encoder_counts,
        # the drive's speed: the count difference over 4 SYNC periods (its datasheet)
        "sensors.encoder_speed_window": int(n.speed_window),
        # the LVDT conditioner: a first-order 1 ms demodulator (its datasheet)
        "sensors.lvdt_time_constant_s": n.lvdt_tau_s,
        # its logged current is an ADC channel of its own: the drive regulates its own
        # current measurement (I2 on the winding's current, I13 on the log)
        "sensors.current_in_loop": False})
    if preload_law not in PRELOAD_LAWS:
        raise ValueError(f"preload_law {preload_law!r} not one of {PRELOAD_LAWS}")
    if preload_law == "none" or n.preload_n <= 0.0:
        return model
    if preload_law == "hertz":
        return model.with_dict({"screw.hertz_reference_preload_n": n.preload_n})
    drag = catalogue_preload_drag_nm(n)
    if preload_law == "hertz-fv":
        return model.with_dict({"screw.hertz_reference_preload_n": n.preload_n,
                                "screw.rolling_friction": rolling_friction_for_drag(model, drag)})
    return model.with_dict({"screw.hertz_reference_preload_n": n.preload_n,
                            "screw.preload_drag_nm_per_n": drag / n.preload_n})


FRICTION_SPLIT = "unknown"
"""The datasheet model's friction split (`bench.gap.library.FRICTION_SPLITS`): a datasheet
gives a total friction, not where it acts (at the nut or at the screw), so the diagnoses
fit it where it shows (docs/gap.md, "Inputs")."""


def bench_ecu_cascade(cp: ControllerParams | None = None) -> Cascade:
    """The bench's ECU (position P on the LVDT, speed PI, every SYNC) as numbers."""
    cp = cp or ControllerParams()
    return Cascade.like_bench_ecu(cp.position_kp_rad_s_per_m, cp.speed_kp_a_s_per_rad,
                                  cp.speed_ki_a_per_rad, cp.speed_limit_rad_s,
                                  cp.current_limit_a)


def maneuver(duration_s: float) -> dict[str, np.ndarray]:
    """The diagnosis maneuver's set-points and the rig's 2 kN sine load per period."""
    prof = excitation(duration_s, LOAD_N)
    dt = NOMINAL.sync_period_s
    t = np.arange(int(round(duration_s / dt))) * dt
    return {"sp_pos": prof.position(t), "sp_spd": prof.speed(t),
            "mode": np.full(len(t), float(prof.mode)),
            "load": LOAD_N * np.sin(2 * math.pi * LOAD_HZ * t)}


# --- effects in the independent physics ------------------------------------------------
def _lu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _pm(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi) * rng.choice([-1.0, 1.0]))


def _draws(rng: np.random.Generator) -> dict[str, Callable[[], dict[str, float]]]:
    n = NOMINAL
    return {
        "backlash": lambda: {"backlash_m": rng.uniform(5e-6, 100e-6)},
        "friction": lambda: {"friction_scale": _lu(rng, 1.5, 4.0)},
        "viscous": lambda: {"viscous_scale": _lu(rng, 10.0, 200.0)},
        "stiffness": lambda: {"hertz_n_per_m15": n.hertz_n_per_m15 * _lu(rng, 3e-3, 0.1)},
        "preload": lambda: {"preload_n": n.preload_n * rng.uniform(0.0, 0.5)},
        "sensor_delay": lambda: {"sensor_delay_periods": float(rng.integers(1, 6))},
        "lvdt_delay": lambda: {"lvdt_delay_periods": float(rng.integers(1, 6))},
        "lvdt_lag": lambda: {"lvdt_extra_lag_s": rng.uniform(1e-3, 10e-3)},
        "lvdt_gain": lambda: {"lvdt_gain": 1.0 + _pm(rng, 0.005, 0.05)},
        "lvdt_offset": lambda: {"lvdt_offset_m": _pm(rng, 5e-6, 200e-6)},
        "encoder_gain": lambda: {"encoder_gain": 1.0 + _pm(rng, 0.005, 0.05)},
        "current_offset": lambda: {"current_offset_a": _pm(rng, 0.05, 0.5)},
        "resistance": lambda: {"resistance_ohm": n.resistance_ohm * _lu(rng, 1.5, 4.0)},
        "kt": lambda: (lambda f: {"kt_nm_per_a": n.kt_nm_per_a * f,
                                  "ke_v_s_per_rad": n.ke_v_s_per_rad * f})(
            1.0 + _pm(rng, 0.02, 0.15)),
        "inertia": lambda: {"inertia_kg_m2": n.inertia_kg_m2 * (1.0 + _pm(rng, 0.05, 0.5))},
        "lead": lambda: {"lead_m": n.lead_m * (1.0 + _pm(rng, 0.002, 0.02))},
    }


POOL = ("backlash", "friction", "viscous", "stiffness", "preload", "sensor_delay",
        "lvdt_delay", "lvdt_lag", "lvdt_gain", "lvdt_offset", "encoder_gain",
        "current_offset", "resistance", "kt", "inertia", "lead")
"""Effects injected (the library's names, in the independent physics). Not injected:
stribeck, thermal_drift (no thermal model here), log_skew (a logger's fault, not the
actuator's)."""


TRUTH_KIND = {"friction_scale": "factor", "backlash_m": "lost_motion_m",
              "sensor_delay_periods": "delay_s", "lvdt_delay_periods": "delay_s",
              "lvdt_extra_lag_s": "lvdt_lag_s", "current_offset_a": "current_offset_a",
              "lvdt_offset_m": "lvdt_offset_m", "lvdt_gain": "lvdt_gain",
              "encoder_gain": "encoder_gain", "lead_m": "lead_m",
              "resistance_ohm": "resistance_ohm", "kt_nm_per_a": "kt_nm_per_a",
              "preload_n": "preload_n"}
"""The independent actuator's effect parameters whose value states the size of the
family the diagnosis names, in `bench.gap.finding.size_of`'s terms (its backlash is the
wear clearance of the two nut halves, of which the free play is what the preload's
deflection does not take up: BL - 2 d0, I8; its delays whole periods). Not stated: a
viscous or a stiffness change
(the family's size is another quantity) and the inertia (its 2.5e-3 is everything
reflected to the motor; the model's rotor is a part of that)."""


def truth_size(t: Truth, actuator: IndieParams = NOMINAL) -> tuple[str, float, float] | None:
    """(kind, value, no-effect value) of an effect injected into `actuator`
    (`TRUTH_KIND`), None where its value states no size of the family named."""
    from indie_plant.physics import preload_deflection
    for k, v in t.plant.items():
        kind = TRUTH_KIND.get(k)
        if kind is None:
            continue
        if kind == "delay_s":
            return kind, float(v) * actuator.sync_period_s, 0.0
        if kind == "lost_motion_m":
            d0 = preload_deflection(actuator.preload_n, actuator.hertz_n_per_m15)
            return kind, max(float(v) - 2.0 * d0, 0.0), 0.0
        nominal = float(getattr(NOMINAL, k))
        if kind in ("factor", "lvdt_gain", "encoder_gain"):
            nominal = 1.0
        return kind, float(v), nominal
    return None


def draw(name: str, rng: np.random.Generator) -> Truth:
    """One effect at a random magnitude: its indie parameter overrides."""
    return Truth(name, plant=_draws(rng)[name]())


def make_cases(n: int, seed: int, only: str | None = None) -> list[Case]:
    """`n` cases, 30 % nominal and 70 % single, in a shuffled order fixed by `seed`.

    `only`: every case is a single effect of that name (at a random magnitude), for a
    benchmark aimed at one effect; the default draw is unchanged by it."""
    if only is not None and only not in POOL:
        raise ValueError(f"unknown effect {only!r}; injected effects: {', '.join(POOL)}")
    rng = np.random.default_rng(seed)
    if only is None:
        kinds = ["nominal"] * round(0.3 * n)
        kinds = (kinds + ["single"] * (n - len(kinds)))[:n]
        rng.shuffle(kinds)
    else:
        kinds = ["single"] * n
    cases = []
    for i, kind in enumerate(kinds):
        truths = [] if kind == "nominal" else [draw(only or str(rng.choice(POOL)), rng)]
        cases.append(Case(i, kind, truths, int(rng.integers(1, 2**31 - 1))))
    return cases


def generate(case: Case, noise: bool = True, duration_s: float = LOG_S,
             controller: str = "ecu", actuator: IndieParams = NOMINAL) -> Trace:
    """The case's log from the independent `actuator` (healthy, as built) with the case's
    effects: measured columns, no metadata."""
    over: dict[str, float] = {"noise": 1.0 if noise else 0.0}
    for t in case.truths:
        over.update(t.plant)
    params = actuator.with_dict(over)
    m = maneuver(duration_s)
    ctrl = bench_ecu_cascade() if controller == "ecu" else Cascade.own(params)
    cols = indie_simulate(params, m["sp_pos"], m["sp_spd"], m["mode"], m["load"], ctrl,
                          seed=case.noise_seed)
    return Trace(cols, {})


def reference(duration_s: float, seed: int, controller: str,
              actuator: IndieParams = NOMINAL) -> dict[str, Any]:
    """Noise-free nominal log and the generator's noise floor per signal (at least the
    encoder's resolution)."""
    clean = generate(Case(-1, "nominal", [], seed), False, duration_s, controller, actuator)
    a = generate(Case(-1, "nominal", [], seed + 1), True, duration_s, controller, actuator)
    b = generate(Case(-1, "nominal", [], seed + 2), True, duration_s, controller, actuator)
    # at least the encoder's resolution (step / sqrt 12): under the actuator's own loop
    # on the encoder no noise reaches the angle or the speed, whose RMS difference is 0
    step = 2.0 * math.pi / actuator.encoder_counts
    res = {"motor_angle_rad": step / math.sqrt(12.0),
           "motor_speed_rad_s": step / (actuator.speed_window * actuator.sync_period_s)
           / math.sqrt(12.0)}
    floor = {s: max(float(np.sqrt(np.mean((a[s] - b[s]) ** 2)) / math.sqrt(2.0)),
                    res.get(s, 0.0)) for s in SNR_SIGNALS}
    return {"clean": {s: clean[s] for s in SNR_SIGNALS}, "floor": floor}


def floor_snr(case: Case, duration_s: float, ref: dict[str, Any], controller: str,
              actuator: IndieParams = NOMINAL) -> dict[str, float]:
    clean = generate(case, False, duration_s, controller, actuator)
    return {s: float(np.sqrt(np.mean((clean[s] - ref["clean"][s]) ** 2)) / ref["floor"][s])
            for s in SNR_SIGNALS}


RESIM = {"ecu": "bench-ecu", "own": "fitted-cascade"}
"""What the calibration does about each controller (`bench.gap.calibrate.CONTROLLERS`):
the bench's ECU closes the loops (the log was run under it), or, for the actuator's own
controller, which the bench does not know, a generic cascade is identified
(fitted-cascade; measured-current: the measured current drives the model instead)."""


def calibrated_model(seed: int, duration_s: float = LOG_S, controller: str = "ecu",
                     actuator: IndieParams = NOMINAL, identify: str | None = None
                     ) -> tuple[PlantParams, dict[str, Any]]:
    """The datasheet model calibrated (bench.gap.calibrate, its default parameters) on one
    healthy log of the actuator with noise seed `seed + CALIBRATION_SEED_OFFSET`,
    the controller handled as `identify` says (default `RESIM[controller]`)."""
    log = generate(Case(-1, "nominal", [], seed + CALIBRATION_SEED_OFFSET), True,
                   duration_s, controller, actuator)
    base = datasheet_model(actuator)
    cal = calibrate(log, base, default_names(log), controller=identify or RESIM[controller])
    return base.with_dict(cal["params"]), cal


def heldout_residual(model: PlantParams, seed: int, duration_s: float = LOG_S,
                     controller: str = "ecu", actuator: IndieParams = NOMINAL,
                     identified: dict[str, Any] | None = None) -> dict[str, Any]:
    """Goal 4: the model's closed-loop re-simulation of a held-out healthy log (noise seed
    `seed + HELDOUT_SEED_OFFSET`): RMS residual per signal, the noise floor per signal
    (the diagnosis' bootstrap of the noise estimated from that log, without the fast
    model's own error) and their ratio. `identified`: the calibration's `controller`
    entry, how the model re-simulates (default: the bench's ECU)."""
    from bench.gap.calibrate import resim_of
    from bench.gap.problem import build
    log = generate(Case(-1, "nominal", [], seed + HELDOUT_SEED_OFFSET), True, duration_s,
                   controller, actuator)
    p = build(log.measured(), model, holdout_frac=0.5,
              **resim_of(identified or {"method": "bench-ecu"}))
    nominal = p.info["nominal"]
    out: dict[str, Any] = {}
    for s, meas in p.meas.items():
        if s not in nominal or s == "current_demand_a":
            continue
        r = float(np.sqrt(np.nanmean((meas - nominal[s]) ** 2)))
        noise = float(np.sqrt(np.mean([np.mean(b[s] ** 2) for b in p.info["bootstrap"]])))
        out[s] = {"rms": r, "noise_floor": noise, "ratio": r / noise if noise else math.inf,
                  "diagnosis_floor": p.sigma[s]}
    return out


def heldout_level_of(cal: dict[str, Any], seed: int, duration_s: float = LOG_S,
                     controller: str = "ecu", actuator: IndieParams = NOMINAL,
                     log: Trace | None = None) -> dict[str, Any]:
    """The calibration's held-out healthy level (`bench.gap.calibrate.heldout_significance`)
    on the held-out healthy log, noise seed `seed + HELDOUT_SEED_OFFSET` (never a judged
    case: `make_cases` draws the cases' seeds from `seed`'s generator, 1 .. 2^31); every
    judged case's significance test is raised to it x its margin."""
    ho = seed + HELDOUT_SEED_OFFSET
    if log is None:          # `healthy_log`'s, generated once by `run`
        log = healthy_log(seed, duration_s, controller, actuator)
    return heldout_significance(cal, datasheet_model(actuator), [log],
                                [f"independent actuator, healthy, noise seed {ho}"])


def healthy_log(seed: int, duration_s: float = LOG_S, controller: str = "ecu",
                actuator: IndieParams = NOMINAL) -> Trace:
    """The held-out healthy log (noise seed `seed + HELDOUT_SEED_OFFSET`), measured columns
    only."""
    return generate(Case(-1, "nominal", [], seed + HELDOUT_SEED_OFFSET), True, duration_s,
                    controller, actuator)


_STATE: dict[str, Any] = {}


def _init(state: dict[str, Any]) -> None:
    _STATE.update(state)


def run_case(case: Case, duration_s: float = LOG_S, controller: str = "ecu",
             effects: list[str] | None = None) -> dict[str, Any]:
    """Generate, diagnose against the calibrated model (seeing only the log), score."""
    ref, model, act = _STATE["ref"], _STATE["model"], _STATE["actuator"]
    log = generate(case, True, duration_s, controller, act)
    under_controller(log, _STATE.get("controller"))    # re-simulated as calibrated
    t0 = time.perf_counter()
    res = diagnose(log, nominal=model, options=Options(workers=1, effects=effects,
                                                        reference=_STATE.get("reference"),
                                                        friction_split=FRICTION_SPLIT))
    elapsed = time.perf_counter() - t0
    snr_each = {t.name: floor_snr(Case(case.index, case.kind, [t], case.noise_seed),
                                  duration_s, ref, controller, act) for t in case.truths}
    snr_all = floor_snr(case, duration_s, ref, controller, act) if case.truths else {}
    rec = score(case, res.json(), snr_each, snr_all, elapsed, sizes=truth_size)
    rec["truth_values"] = {t.name: t.plant for t in case.truths}
    return rec


def run(n: int, seed: int, workers: int = 2, duration_s: float = LOG_S,
        progress: bool = True, effects: list[str] | None = None, controller: str = "ecu",
        on_result: Callable[[dict[str, Any]], None] | None = None,
        actuator: IndieParams = NOMINAL, scheduler: str | None = None,
        identify: str | None = None, only: str | None = None) -> dict[str, Any]:
    """Calibrate on the healthy calibration log, then run `n` blind cases (`only`: every
    case a single effect of that name, `make_cases`). `actuator`:
    the independent actuator as built (`--indie-set`: e.g. an ablation of one physical
    feature). `identify`: what the calibration does about the controller (default
    `RESIM[controller]`); the blind diagnoses re-simulate as the calibration says (the
    log's ``meta["controller"]``, `bench.gap.problem.drive_of`)."""
    t0 = time.perf_counter()
    identify = identify or RESIM[controller]
    model, cal = calibrated_model(seed, duration_s, controller, actuator, identify)
    t_cal = time.perf_counter() - t0
    held = heldout_residual(model, seed, duration_s, controller, actuator, cal["controller"])
    healthy = healthy_log(seed, duration_s, controller, actuator)
    sig_ref = heldout_level_of(cal, seed, duration_s, controller, actuator, healthy)
    judged_against = reference_of(cal | {"heldout_significance": sig_ref},
                             f"independent-calibration-seed-{seed + CALIBRATION_SEED_OFFSET}")
    under_controller(healthy, cal["controller"])          # re-simulated as calibrated
    judged_against["healthy_logs"] = [healthy]   # the verdicts' model-form term
    ref = reference(duration_s, seed + 7919, controller, actuator)
    cases = make_cases(n, seed, only)
    reserved = {seed + CALIBRATION_SEED_OFFSET, seed + HELDOUT_SEED_OFFSET}
    if any(c.noise_seed in reserved for c in cases):     # the healthy logs are never judged
        raise ValueError("a judged case drew the calibration's or the held-out log's seed")
    job = partial(run_case, duration_s=duration_s, controller=controller, effects=effects)
    results = run_all(job, cases, workers, progress, desc="gap-bench (independent)",
                      unit="case", initializer=_init, initargs=({"ref": ref, "model": model, "actuator": actuator,
                                          "controller": cal["controller"],
                                          "reference": judged_against},),
                      on_result=on_result, leave=True, scheduler=scheduler)
    changed = {k: v for k, v in dataclasses.asdict(actuator).items()
               if v != getattr(NOMINAL, k)}
    return {"generator": "independent", "controller": controller, "seed": seed, "cases": n,
            "only": only,
            "actuator_changes": changed,
            "fidelity": "independent physics (indie_plant)", "log_s": duration_s,
            "library": effects or "all", "friction_split": FRICTION_SPLIT,
            "wall_s": time.perf_counter() - t0, "workers": workers, "floor": ref["floor"],
            "calibration": {"seed": seed + CALIBRATION_SEED_OFFSET, "wall_s": t_cal,
                            "controller": cal["controller"],
                            "params": cal["params"], "ci95": cal["ci95"],
                            "gap_after": cal["gap_after"], "notes": cal["notes"]},
            "heldout_healthy": {"seed": seed + HELDOUT_SEED_OFFSET, "signals": held,
                                "significance": sig_ref},
            "summary": summarise(results), "results": results}

