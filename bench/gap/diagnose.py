"""The gap diagnosis of one log: where the gap lies, which effect causes it, how far it
shrinks (docs/gap.md).

    result = diagnose(trace, holdout=None, nominal=None, options=Options())
    result.json()      # {"localisation": ..., "ranking": [...], "verdict": ...}

Steps:
1. Floors and significance (`bench.gap.problem.build`): sensor noise estimated from the
   log, pushed through the nominal loop (bootstrap); the gap is significant when a
   signal's smoothed residual energy exceeds SIGNIFICANT x its floor. Against a
   calibration that stored its held-out healthy level (`Options.reference`,
   `bench calibrate --holdout`), only where it also exceeds that level x a margin
   (HELDOUT_Z); the JSON and the verdict line say what was judged against. If not:
   verdict "none" (no significant gap) and no fitting.
2. Localisation (`bench.gap.localise`).
3. Every candidate effect fitted alone on the fit part (`bench.gap.fit`), in parallel.
4. Forward selection: the best single effect (lowest BIC) extended by each other
   candidate; the best pair (lowest BIC) among those that remove at least PAIR_GAIN of
   the held-out excess the single leaves replaces the single when that remainder is
   significant (the test of step 1 on the held-out residual) and the pair lowers the
   BIC by more than PAIR_BIC.
5. Held-out shrink of the chosen candidate (on the holdout log, or the part of the log
   not used in the fit); below MIN_SHRINK_PCT the verdict is "unexplained".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.gap import alias as AL
from bench.gap import effects as E
from bench.gap import families as F
from bench.gap import limitcycle as LC
from bench.gap import localise as LZ
from bench.gap import modelform as MF
from bench.gap import resim as R
from bench.gap import schedule as S
from bench.gap.finding import describe, faint, insignificant
from bench.gap.fit import Fit, fit
from bench.gap.library import FRICTION_SPLITS, SPLIT_NOTE
from bench.gap.problem import Problem, build, fill_gaps, not_representable
from bench.gap.refine import refine
from bench.gap.scores import excess, shrink_pct
from bench.runtime.workers import make_pool
from bench.signals.integrity import log_integrity
from bench.signals.trace import Trace
from plant_rt.params import PlantParams

SIGNIFICANT = 1.5       # smoothed residual energy / floor above which a gap is significant
SIGNIFICANT_Z = 8.0     # ... or 1 + Z sqrt(2 L / n) if larger (L: the smoothed noise
                        # residual's correlation length); Z set on 60 nominal full-fidelity
                        # logs (seeds 5000-5059, not the benchmark's): the statistic's
                        # tail is heavier than chi-square (stiction events in dwells)
MIN_SHRINK_PCT = 50.0   # held-out shrink below which nothing explains the gap
PAIR_BIC = 10.0         # BIC improvement a pair needs over the best single
PAIR_GAIN = 0.5         # ... and the fraction of the single's held-out excess it removes
HELDOUT_Z = SIGNIFICANT_Z
"""Against a calibration that measured its held-out healthy level m_s (the statistic below
on a healthy log the calibration did not fit): a gap is significant on signal s only where
the log's smoothed energy exceeds max(default threshold, m_s x margin_s), margin_s =
1 + HELDOUT_Z sqrt(2) sqrt(2 L_s / n): the statistic's relative spread sqrt(2 L / n) (n/L
effective samples of a squared residual), sqrt(2) for two independent draws (the held-out
log and the judged one), at the default test's own tail bound Z (set on nominal logs of
the bench's generator, not on any benchmark), L and n from the held-out log."""
PAIR_MEMBERS = 2        # members of each other family tried as a pair's second effect
TIE = 0.95              # candidates of the verdict's size explaining >= TIE of what it
                        # explains on held-out data (over the nominal for a single, over
                        # the best single for a pair) are reported as "also explains"


@dataclass
class Options:
    """How to diagnose (all optional)."""
    model: str = "plant"
    effects: Sequence[str] | None = None       # candidate names (None: the whole library)
    holdout_frac: float = 0.5                  # without a holdout log: the last part held out
    workers: int = 2
    scheduler: str | None = None               # a Dask scheduler (None: local cluster)
    encoder: str = "absolute"
    fit_always: bool = False                   # fit candidates even without a significant gap
    bootstrap: int = 6
    progress: bool = False
    reference: dict[str, Any] | None = None    # the calibration judged against (name and its
                                               # held-out healthy level, `heldout_level`)
    friction_split: str = "model"              # where the model's Coulomb friction acts:
                                               # "model" (known) or "unknown" (the nut
                                               # friction share fitted, library.NUT_SHARE)


@dataclass
class Candidate:
    fit: Fit
    bic: float = math.nan
    aic: float = math.nan
    heldout: dict[str, float] = field(default_factory=dict)     # energies on held-out data
    heldout_smooth: dict[str, float] = field(default_factory=dict)
    heldout_excess: float = math.nan
    fit_excess: float = math.nan
    suspect: list[str] = field(default_factory=list)    # implausible values, one line each
    edge: list[str] = field(default_factory=list)       # parameters at a family's bound
    insignificant: list[str] = field(default_factory=list)  # added effects whose interval
                                                    # holds their no-effect value
    faint: list[str] | None = None      # added effects no signal shows above the floor


@dataclass
class Result:
    """Everything the diagnosis found (the JSON plus arrays for the report)."""
    localisation: dict[str, Any]
    ranking: list[Candidate]
    verdict: str
    problem: Problem
    holdout: Problem | None
    chosen: Candidate | None
    gap_before_heldout: dict[str, float]
    significant: bool
    ties: list[str] = field(default_factory=list)
    finding: dict[str, Any] | None = None      # the chosen candidate in words (finding.py)

    def json(self) -> dict[str, Any]:
        from bench.gap.result_json import to_json
        return to_json(self)


# --- workers -------------------------------------------------------------------------

Task = tuple[tuple[str, ...], list[dict[str, float]] | None]   # (names, start)


def _task(p: Problem, h: Problem | None, names: tuple[str, ...],
          start: list[dict[str, float]] | None) -> Candidate:
    return evaluate(p, h, names, start)


def heldout_eval(p: Problem, h: Problem | None, effects: Sequence[E.Effect],
                 thetas: Sequence[dict[str, float]]
                 ) -> tuple[dict[str, float], float, dict[str, float]]:
    """Energies, excess and smoothed energies of the held-out data with `effects` at
    `thetas`."""
    if h is not None:
        sim = h.simulate(effects, thetas)
        en, sm = h.energies(sim, 0, h.n), h.energies_smooth(sim, 0, h.n)
    else:
        sim = p.simulate(effects, thetas)
        en, sm = p.energies(sim, p.n_fit, p.n), p.energies_smooth(sim, p.n_fit, p.n)
    return en, float(sum(e - 1.0 for e in en.values())), sm


def evaluate(p: Problem, h: Problem | None, names: Sequence[str],
             start: list[dict[str, float]] | None = None) -> Candidate:
    """Fit `names` on the fit part and evaluate on held-out data (a candidate whose fit
    fails numerically is returned with an infinite RSS, not raised)."""
    try:
        f = fit(p, names, start)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        effs = [E.get(n) for n in names]
        th = [e.nominal(p.base) for e in effs]
        f = Fit(tuple(names), th, [{} for _ in effs], math.inf, 1, 1, 0, 1.0, False, str(exc))
        return Candidate(f, heldout={s: math.inf for s in R.SIGNALS},
                         heldout_excess=math.inf, fit_excess=math.inf)
    effs = [E.get(n) for n in names]
    en, ex, sm = heldout_eval(p, h, effs, f.theta)
    c = Candidate(f, heldout=en, heldout_excess=ex, heldout_smooth=sm)
    c.fit_excess = f.rss / (f.n / len(R.SIGNALS)) - len(R.SIGNALS)
    flag(c, p)
    if len(names) > 1:
        c.insignificant = insignificant(p, f)
    return c


def flag(c: Candidate, p: Problem) -> None:
    """The candidate's trouble: values beyond the family's plausible range
    (`families.suspect`) and parameters on a bound that is not their no-effect value
    (`Fit.at_bound`)."""
    objs = c.fit.objs or [E.get(n) for n in c.fit.effects]
    nom = {k: v for e in objs for k, v in e.nominal(p.base).items()}
    c.suspect = F.suspect(c.fit.params_dict(), nom)
    c.edge = c.fit.bounded()


def _strip(p: Problem) -> Problem:
    """A copy without the bulky diagnostics (for worker processes): every other field is
    the problem's (a field left out would fall back to its default in the workers)."""
    return dataclasses.replace(p, holdout=None, info={}, _cache={})


def _run(tasks: Sequence[Task], p: Problem, h: Problem | None, pool: Any = None,
         bar: Any = None) -> list[Candidate]:
    """Evaluate `tasks` in `pool` (worker processes, `bench.gap.schedule`) or in-process;
    the results in task order."""
    if pool is None or len(tasks) <= 1:
        out = []
        for t in tasks:
            out.append(evaluate(p, h, *t))
            if bar is not None:
                bar.update(1)
        return out
    return S.on_pool(_task, evaluate, _strip, tasks, p, h, pool, bar)


# --- the diagnosis --------------------------------------------------------------------

def thresholds(p: Problem, n: int | None = None) -> dict[str, float]:
    """Per-signal significance thresholds on the smoothed residual energy of `n`
    samples (default: the whole log)."""
    L = p.info.get("corr_smooth", {})
    n = p.n if n is None else max(n, 1)
    return {s: max(SIGNIFICANT, 1.0 + SIGNIFICANT_Z * math.sqrt(2.0 * L.get(s, 1.0) / n))
            for s in R.SIGNALS}


def significance(p: Problem, reference: dict[str, Any] | None = None
                 ) -> tuple[bool, dict[str, float], dict[str, float]]:
    """(significant, raw energies, smoothed energies) of the nominal residual: significant
    when any signal's smoothed energy exceeds its threshold (`thresholds`, raised to the
    calibration's held-out healthy level x margin when `reference` stores one)."""
    nominal = p.info["nominal"]
    raw = p.energies(nominal, 0, p.n)
    sm = p.energies_smooth(nominal, 0, p.n)
    thr = calibrated_thresholds(thresholds(p), reference)
    return any(sm[s] > thr[s] for s in R.SIGNALS), raw, sm


def heldout_level(p: Problem) -> dict[str, Any]:
    """Measured once at calibration time on a held-out healthy log (`p` built with the
    calibrated model, as the diagnosis builds it): per signal the significance statistic
    (smoothed residual energy / floor) the calibrated model leaves there, and its margin
    (HELDOUT_Z)."""
    _, _, sm = significance(p)
    L = p.info.get("corr_smooth", {})
    margin = {s: 1.0 + HELDOUT_Z * math.sqrt(2.0) * math.sqrt(2.0 * L.get(s, 1.0) / p.n)
              for s in R.SIGNALS}
    held = p.energies(p.info["nominal"], p.n_fit, p.n)   # the part a diagnosis holds out
    return {"level": {s: float(sm[s]) for s in R.SIGNALS}, "margin": margin,
            "energy": {s: float(held[s]) for s in R.SIGNALS}, "samples": p.n}


def calibrated_thresholds(thr: dict[str, float], reference: dict[str, Any] | None
                          ) -> dict[str, float]:
    """The default thresholds `thr`, each raised to the reference's held-out healthy level
    x its margin where the reference stores one (unchanged otherwise)."""
    level = (reference or {}).get("level") or {}
    margin = (reference or {}).get("margin") or {}
    return {s: max(t, level[s] * margin.get(s, 1.0)) if level.get(s) is not None else t
            for s, t in thr.items()}


def basis(reference: dict[str, Any], sm: dict[str, float], default: dict[str, float]
          ) -> dict[str, Any]:
    """What the significance test was judged against (a calibration), with the one line
    the verdict prints."""
    name = reference.get("name", "?")
    level = reference.get("level")
    thr = calibrated_thresholds(default, reference)
    out: dict[str, Any] = {"calibration": name, "heldout_logs": reference.get("logs"),
                           "level": level, "margin": reference.get("margin"),
                           "default_threshold": default, "threshold": thr}
    if not level:
        out["line"] = (f"judged against calibration {name}: its held-out healthy level is "
                       "unknown (calibrated without --holdout), the default threshold "
                       "applies")
        return out
    s = max(thr, key=lambda k: sm[k] / thr[k])
    raised = [k for k in thr if thr[k] > default[k]]
    out["line"] = (f"judged against calibration {name}: held-out healthy level "
                   f"x{level[s]:.3g} on {s} (threshold {thr[s]:.3g}"
                   + (f" = level x margin {reference['margin'][s]:.3g}" if s in raised
                      else ", the default") + f"; log {sm[s]:.3g})")
    return out


def diagnose(trace: Trace, holdout: Trace | None = None, nominal: PlantParams | None = None,
             options: Options | None = None,
             log: Callable[[str], None] | None = None) -> Result:
    """Diagnose the gap between `trace` (a log, measured columns only are read) and the
    nominal model `nominal` (thesis parameters when None)."""
    o = options or Options()
    say = log or (lambda s: None)
    if o.model != "plant":
        from bench.gap.models import check_model
        check_model(o.model)
    names = list(o.effects) if o.effects else E.names()
    for n in names:
        E.get(n)
    if o.friction_split not in FRICTION_SPLITS:
        raise BenchError(f"friction split {o.friction_split!r}: choose from "
                         f"{', '.join(FRICTION_SPLITS)}")
    base = nominal or PlantParams()
    frac = 0.0 if holdout is not None else o.holdout_frac
    if holdout is None and not 0.1 <= frac <= 0.9:
        raise BenchError("the held-out part must be 10-90 % of the log")
    pools: list[Any] = []
    try:
        return _diagnose(trace, holdout, base, o, names, frac, say, pools)
    finally:
        for pool in pools:
            pool.shutdown(wait=False, cancel_futures=True)


def _diagnose(trace: Trace, holdout: Trace | None, base: PlantParams, o: Options,
              names: list[str], frac: float, say: Callable[[str], None], pools: list[Any]
              ) -> Result:
    say("estimating the noise floor (bootstrap through the nominal loop)")
    trace = fill_gaps(trace.measured())
    if holdout is not None:
        holdout = fill_gaps(holdout.measured(), "held-out log")
    p = build(trace.measured(), base, frac, bootstrap=o.bootstrap, encoder=o.encoder,
              model=o.model, friction_split=o.friction_split)
    h = None
    if holdout is not None:
        h = build(holdout.measured(), base, 0.0, bootstrap=o.bootstrap, encoder=o.encoder,
                  purpose="held-out log", model=o.model)
        h.n_fit = 0
    sig, raw, sm = significance(p, o.reference)
    # worker processes start in the background while the gap is localised (only when
    # there is something to fit: a log within the noise floor costs no process start)
    pool = None
    if (sig or o.fit_always) and o.workers > 1 and len(names) > 1:
        pool = make_pool(o.workers, wait=False, scheduler=o.scheduler)
        pools.append(pool)
        pool.preload(S.warm_worker)
    loc, ho_en, ho_ex = _localisation(trace, holdout, p, h, frac, (sig, raw, sm), say)
    if o.reference is not None:
        b = basis(o.reference, sm, loc["significance"]["threshold"])
        loc["significance"]["threshold"] = b["threshold"]
        loc["significance"]["judged_against"] = b
    skipped = [] if o.model == "plant" else not_representable(p, names)
    absent = [n for n in names if not E.get(n).available(p.base)]
    names = [n for n in names if n not in skipped and n not in absent]
    loc["model"] = {"name": o.model, "fidelity": "fast: averaged PWM, massless balls "
                    "(drive.pwm_mode=averaged, sim.ball_model=quasistatic), ~240x real time"
                    if o.model == "plant" else "monitoring model (rigid screw, no PWM)",
                    "effects_not_representable": skipped,
                    "effects_without_a_place": absent,
                    "load": R.load_note(p.drive, o.model),
                    "friction_split": SPLIT_NOTE[o.friction_split],
                    "nominal_differs_from_thesis": {k: v[1] for k, v in
                                                    PlantParams().diff(base).items()}}
    if not sig and not o.fit_always:
        return Result(loc, [], "none", p, h, None, ho_en, False)
    # -- singles -------------------------------------------------------------------------
    bar = None
    if o.progress:
        from tqdm import tqdm
        bar = tqdm(total=len(names) + PAIR_MEMBERS * len({F.family(n) for n in names}),
                   unit="fit",
                   desc="gap", leave=False)
    say(f"fitting {len(names)} candidate effects")
    singles, pairs, best, L = _select(names, p, h, pool, bar, say, o.reference)
    if bar is not None:
        bar.close()
    healthy = (o.reference or {}).get("energy")
    if healthy:                               # the shrink above the healthy level
        loc["heldout_excess"] = {
            "before": excess(ho_en, o.reference), "healthy_energy": healthy,
            "rule": "the held-out shrink counts, per signal, only the energy above the "
                    "calibration's held-out healthy energy"}
    chosen, verdict, ranking, ties = _verdict(p, h, L, o, (base, frac), (singles, pairs, best),
                                              (sig, ho_ex, ho_en), loc, say)
    finding = None
    if chosen is not None and math.isfinite(chosen.fit.rss):
        flag(chosen, p)
        finding = describe(p, chosen.fit, chosen.suspect, chosen.edge)
        alias = loc["selection"].get("lead_or_lvdt_gain")
        if alias and not alias["separated"] and verdict == chosen.fit.name:
            finding["line"] = f"{alias['line']} ({finding['line']})"
    lc = LC.note(p, names)          # a note under the verdict (the summary prints it)
    if lc is not None:
        loc["limit_cycle"] = lc
    return Result(loc, ranking, verdict, p, h, chosen, ho_en, sig, ties, finding)


def _verdict(p: Any, h: Any, L: float, o: Options, model: tuple[PlantParams, float],
             cands: tuple[list[Any], list[Any], Any], gap: tuple[bool, float, Any],
             loc: dict[str, Any], say: Callable[[str], None]
             ) -> tuple[Any, str, list[Any], list[str]]:
    """The chosen candidate (`_choose`, `_settle_alias`) with its fit refined and its
    model-form term (`refine`, `_model_form`): a pair whose added effect's interval, as
    the verdict reports it, holds its no-effect value gives way, and the rule is taken
    again without it."""
    (singles, pairs, best), (sig, ho_ex, ho_en) = cands, gap
    while True:
        picked, verdict, ranking, ties, loc["selection"] = _choose(
            singles, pairs, best, p, h, ho_ex, sig, L, o.reference, ho_en)
        chosen, verdict, ranking, ties = _settle_alias(
            p, h, L, picked, singles, verdict, ranking, ties, loc["selection"],
            (o.reference or {}).get("load_current_ratio"))
        if chosen is None or not math.isfinite(chosen.fit.rss):
            return chosen, verdict, ranking, ties
        say("refining the verdict's fit against the model at its own fidelity")
        chosen.fit, loc["selection"]["fast_model_correction"] = refine(p, chosen.fit)
        chosen.fit = _model_form(p, chosen.fit, o, *model, loc["selection"], say)
        if len(picked.fit.effects) == 1 or not (late := insignificant(p, chosen.fit)):
            return chosen, verdict, ranking, ties
        picked.insignificant = late


def _model_form(p: Problem, f: Fit, o: Options, base: PlantParams, frac: float,
                selection: dict[str, Any], say: Callable[[str], None]) -> Fit:
    """The verdict's fit `f` with the model-form term of the calibration's held-out
    healthy log (`bench.gap.modelform`; `f` itself without one); `selection` gets what
    was done (`model_form`)."""
    if (o.reference or {}).get("healthy_logs"):
        say("fitting the verdict on the calibration's held-out healthy log")
    g, form = MF.apply(p, f, o.reference, base, frac, o.bootstrap, o.encoder, o.model,
                       o.friction_split)
    if form is not None:
        selection["model_form"] = form
    return g


def _localisation(trace: Trace, holdout: Trace | None, p: Any, h: Any, frac: float,
                  significant: tuple[bool, Any, Any], say: Callable[[str], None]
                  ) -> tuple[dict[str, Any], Any, Any]:
    """The localisation of the gap with the log's integrity, the significance test and
    the held-out gap before any fit: (loc, held-out energy, held-out excess)."""
    sig, raw, sm = significant
    nominal_sim = p.info["nominal"]
    f0 = LZ.command_fundamental(p, trace.meta.get("fundamental_hz") if trace.meta else None)
    log_cols = {c: np.asarray(trace[c], float) for c in
                ("current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m")}
    if "current_demand_a" in trace:
        log_cols["current_demand_a"] = np.asarray(trace["current_demand_a"], float)
    say("localising the gap (signals, paths, regimes, frequency bands)")
    loc = LZ.localise(p, nominal_sim, log_cols, p.info["noisy_cols"], p.info["nominal_cols"],
                      f0)
    loc["log"] = log_integrity(trace, holdout)
    loc["significance"] = {
        "significant": sig, "threshold": thresholds(p),
        "energy": raw, "energy_smoothed": sm,
        "noise_sigma": p.noise_sigma, "floor": p.sigma, "model_floor": p.model_floor,
        "bootstrap_max_smoothed": {s: max(b[s] for b in p.info["bootstrap_energy_smooth"])
                                   for s in R.SIGNALS},
    }
    ho_en, ho_ex, _ = heldout_eval(p, h, [], [])
    loc["heldout"] = {"source": "holdout log" if h is not None else
                      f"last {frac * 100:.0f} % of the log",
                      "samples": h.n if h is not None else p.n - p.n_fit,
                      "energy_before": ho_en, "excess_before": ho_ex}
    return loc, ho_en, ho_ex


def _choose(singles: list[Any], pairs: list[Any], best: Any, p: Any, h: Any, ho_ex: Any,
            sig: bool, L: Any, reference: dict[str, Any] | None = None,
            ho_en: dict[str, float] | None = None
            ) -> tuple[Any, str, list[Any], list[str], dict[str, Any]]:
    """The chosen candidate (the best single, or a pair by the rule in the selection
    record), the verdict, the ranking (every candidate by BIC), the candidates of other
    families tied with the chosen one and the selection record. A held-out gap the best
    single leaves is significant by the same rule as the log's (raised to a calibration's
    held-out healthy level x margin, `reference`). A pair whose added effect is suspect
    (`flag`) does not replace the single: a second effect of implausible size is more
    likely the first one's misfit absorbed; nor does one whose added effect's interval
    holds its no-effect value (`finding.holds_no_effect`: friction x0.99 [0.89, 1.10]
    beside a delay is no second effect), nor one whose added effect no signal shows
    above the floor (`finding.faint`). A suspect best single gives way to a
    plausible one (`alias.plausible_best`: an LVDT gain of 1.03 read as a lead 3 % long)."""
    best = AL.plausible_best(best, singles, PAIR_BIC)
    chosen = best
    remaining = leaves_gap(best, p, h, reference)

    def above(c: Any) -> float:
        """The held-out excess of `c` the calibration's healthy model does not leave
        (`excess`; the whole excess without a healthy energy): what an effect can explain,
        the quantity the verdict's shrink counts."""
        if (reference or {}).get("energy") and getattr(c, "heldout", None):
            return excess(c.heldout, reference)
        return float(c.heldout_excess)

    better = [c for c in pairs if above(c) < (1.0 - PAIR_GAIN) * above(best)]
    plausible = [c for c in better if not getattr(c, "suspect", None)]
    null = [c for c in plausible if getattr(c, "insignificant", None)]
    plausible = [c for c in plausible if not getattr(c, "insignificant", None)]
    weak = []              # BIC-better pairs whose added effect no signal shows (`faint`)
    for bp in sorted(plausible, key=lambda c: c.bic) if remaining else []:
        if bp.bic >= best.bic - PAIR_BIC:
            break
        bp.faint = faint(p, bp.fit) if getattr(bp, "faint", None) is None else bp.faint
        if not bp.faint:
            chosen = bp
            break
        weak.append(bp)
    # the verdict's shrink, of the held-out gap above a calibration's healthy energy where
    # it stored one (`excess`: the whole excess otherwise, as the pair rule and the ties)
    shrink = (shrink_pct(ho_ex, chosen.heldout_excess) if ho_en is None else
              shrink_pct(excess(ho_en, reference), excess(chosen.heldout, reference)))
    verdict = chosen.fit.name if shrink >= MIN_SHRINK_PCT and sig else (
        "unexplained" if sig else "none")
    ranking = sorted(singles + pairs, key=lambda c: (c.bic, c is not chosen))
    before = (excess(ho_en, reference) if ho_en is not None and (reference or {}).get("energy")
              else ho_ex)
    ref = before if chosen is best else above(best)
    gain = ref - above(chosen)
    tied = [c.fit.name for c in ranking if c is not chosen
            and len(c.fit.effects) == len(chosen.fit.effects)
            and gain > 0 and ref - above(c) >= TIE * gain]
    ties = F.ties_across(chosen.fit.name, tied)
    selection = {"corr_length_samples": L, "best_single": best.fit.name,
                 "best_single_leaves_significant_heldout_gap": remaining,
                 "chosen": chosen.fit.name, "heldout_shrink_pct": shrink,
                 "min_shrink_pct": MIN_SHRINK_PCT,
                 "indistinguishable_from_chosen": ties,
                 "same_family_forms": [t for t in tied if t not in ties],
                 "pairs_rejected_as_suspect": [c.fit.name for c in better
                                               if getattr(c, "suspect", None)],
                 "pairs_rejected_as_insignificant": [c.fit.name for c in null],
                 "pairs_rejected_below_floor": [c.fit.name for c in weak],
                 "rule": ("a pair replaces the best single when the single leaves a "
                          f"significant held-out gap, the pair removes >= {PAIR_GAIN:.0%} "
                          f"of it, no value of it is suspect, its added effect's 95 % interval "
                          "does not hold that effect's no-effect value, the effect shows "
                          "above the floor on some signal and its BIC is lower "
                          f"by > {PAIR_BIC:g}; 'unexplained' if the held-out shrink < "
                          f"{MIN_SHRINK_PCT:.0f} %")}
    return chosen, verdict, ranking, ties, selection


def _settle_alias(p: Any, h: Any, L: float, chosen: Any, singles: list[Any], verdict: str,
                  ranking: list[Any], ties: list[str], selection: dict[str, Any],
                  ratio: float | None) -> tuple[Any, str, list[Any], list[str]]:
    """An LVDT gain or a lead error chosen, alone or in a pair (the pair fitted again with
    the other, `alias.swapped_pair`, and ranked): the one the current's slope on the
    load-cell force points to (`alias.settle`), recorded in `selection`; where the log
    cannot tell them apart the other stays among the ties and the finding says so."""
    twin = AL.swapped_pair(chosen, singles, lambda n, th: evaluate(p, h, n, th), ranking)
    if twin is not None and all(c is not twin for c in ranking):
        twin.bic, twin.aic = twin.fit.bic(L), twin.fit.aic(L)
        ranking = sorted([*ranking, twin], key=lambda c: (c.bic, c is not chosen))
    new, rec = AL.settle(p, chosen, [*singles, twin] if twin else singles, ratio)
    if rec is None:
        return chosen, verdict, ranking, ties
    selection["lead_or_lvdt_gain"] = rec
    other = AL.swap(chosen.fit.name) or ""     # settled: the chosen holds one of the two
    if rec["separated"]:
        ties = [t for t in ties if t not in (chosen.fit.name, other)]
        if new is not chosen:
            if verdict == chosen.fit.name:
                verdict = new.fit.name
            selection["chosen"] = new.fit.name
        return new, verdict, ranking, ties
    return chosen, verdict, ranking, ties if other in ties else [*ties, other]


def leaves_gap(best: Any, p: Any, h: Any, reference: dict[str, Any] | None) -> bool:
    """Whether candidate `best` leaves a significant held-out gap: the significance test
    of the log on its held-out residual (raised to a calibration's held-out healthy level
    x margin, `reference`)."""
    n_ho = h.n if h is not None else p.n - p.n_fit
    thr_ho = calibrated_thresholds(thresholds(h if h is not None else p, n_ho), reference)
    return any(best.heldout_smooth.get(s, 0.0) > thr_ho[s] for s in R.SIGNALS)


def _select(names: Sequence[str], p: Problem, h: Problem | None, pool: Any, bar: Any,
            say: Callable[[str], None], reference: dict[str, Any] | None = None
            ) -> tuple[list[Candidate], list[Candidate], Candidate, float]:
    """Singles ranked by BIC, then the pairs of the best single (forward selection), unless
    it leaves no significant held-out gap (no pair could then replace it: `_choose`). The
    best single is the one the verdict's rules take: a plausible alias in place of a
    suspect best (`alias.plausible_best`), of an LVDT gain and a lead the one the load cell
    points to (`alias.base_single`)."""
    singles = _run([((n,), None) for n in names], p, h, pool, bar)
    ref = min(singles, key=lambda c: c.fit.rss)
    L = max(ref.fit.corr_len, 1.0)
    for c in singles:
        c.bic, c.aic = c.fit.bic(L), c.fit.aic(L)
    singles.sort(key=lambda c: c.bic)
    best = AL.base_single(p, AL.plausible_best(singles[0], singles, PAIR_BIC), singles,
                          (reference or {}).get("load_current_ratio"))
    # -- forward selection: the best single with the best PAIR_MEMBERS members of each
    # other family (a member of its own family is another form of the same mechanism; the
    # member best alone need not complete a pair: a delay in the loop beside a log-side one)
    pairs: list[Candidate] = []
    mine = F.family(best.fit.effects[0])
    seen: dict[str, int] = {}
    others = []
    for c in singles:
        fam = F.family(c.fit.effects[0])
        if math.isfinite(c.fit.rss) and fam != mine and seen.get(fam, 0) < PAIR_MEMBERS:
            seen[fam] = seen.get(fam, 0) + 1
            others.append(c)
    if others and not leaves_gap(best, p, h, reference):
        say(f"{best.fit.name} leaves no significant held-out gap: no pairs")
        others = []
    if others:
        say(f"forward selection: {best.fit.name} + the best {PAIR_MEMBERS} of each other "
            f"family ({len(others)} pairs)")
        tasks = [((best.fit.effects[0], c.fit.effects[0]), [best.fit.theta[0], c.fit.theta[0]])
                 for c in others]
        pairs = _run(tasks, p, h, pool, bar)
        for c in pairs:
            c.bic, c.aic = c.fit.bic(L), c.fit.aic(L)
    return singles, pairs, best, L
