"""Populations of runs: thresholds from the spread of held-out healthy runs, and a
detection rate and a false-alarm rate per condition instead of a single verdict.

Thresholds (`calibrate_loads`): per load, each calibration run in turn is held out, a
baseline is built from the others and the held-out run's cycles are scored (`loro`), so
every calibration score is that of a cycle its baseline did not see, and the run-to-run
differences are in the scores. The threshold of a feature is the upper (1 - alpha /
n_features) prediction bound of one cycle of a healthy run that is not among them
(`thresholds`, `spread.pooled`): the transformed scores (log for the scans and the index
maximum, cube root for the chi-square-like periodic power, the signed value for level and
reversal) as runs and cycles, the spreads within and between runs pooled over the loads,
alpha the false-alarm rate aimed at (0.05) shared by the features (Bonferroni). With
fewer than 3 calibration runs the between-run spread is not estimated and the thresholds
are provisional (`Calibration.provisional`). They come from healthy calibration runs
only, never from a fault's cycles.

The plain reference (`zscore_score`): a per-sample z-score of the current against the
healthy mean at the same aligned sample (all phases), the cycle's score its largest |z|;
its threshold set the plain way from the same held-out scores (`prediction_bound`:
independent cycles, log-normal, alpha), and also, for a comparison at the same
false-alarm rate, so that it flags as many held-out healthy cycles as the bench's
detector (`matched_threshold`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig.baseline import MIN_CYCLES, LoadBaseline, build_load, residuals
from bench.rig.cycles import Cycle
from bench.rig.features import (
    FEATURES,
    NAMING_ONLY,
    CycleFeatures,
    assess,
    cycle_features,
    location,
)
from bench.rig.offsets import signed_level
from bench.rig.play import PLAY, PLAY_OF, play_score
from bench.rig.spread import MIN_RUNS, Spread, pooled, spread

ALPHA = 0.05


@dataclass
class Calibration:
    """Thresholds of one load and the held-out healthy scores they came from."""
    load: float
    runs: list[int]
    thresholds: dict[str, float]
    scores: dict[str, list[float]]        # leave-one-run-out healthy scores per feature
    alpha: float
    score_runs: list[int] = field(default_factory=list)    # the run of each score
    spreads: dict[str, Spread] = field(default_factory=dict)
    # the plain reference's threshold from the same held-out scores (`zscore_score`; the
    # plain way: independent cycles, log-normal bound at alpha)
    zscore_threshold: float = float("nan")

    @property
    def provisional(self) -> bool:
        """Fewer than `spread.MIN_RUNS` calibration runs: the between-run spread is not
        estimated, and every verdict against these thresholds says so."""
        return len(self.runs) < MIN_RUNS

    def to_json(self) -> dict[str, Any]:
        return {"load": self.load, "runs": self.runs, "thresholds": self.thresholds,
                "loro_scores": self.scores, "loro_runs": self.score_runs,
                "alpha": self.alpha, "provisional": self.provisional,
                "zscore_threshold": self.zscore_threshold,
                "spreads": {k: v.to_json() for k, v in self.spreads.items()},
                "method": METHOD.format(n=len(set(self.thresholds) - set(NAMING_ONLY))),
                "nulls": {k: list(NULLS.get(k, ("log", 0))) for k in self.thresholds}}


METHOD = ("leave-one-run-out over the calibration runs; per feature the upper prediction "
          "bound of one cycle of a healthy run not among them, from the spread within and "
          "between runs of its transformed held-out scores (Student-t, Welch-Satterthwaite "
          "degrees of freedom; log for the scans, the index maximum, the rattle and the combined "
          "play, cube root for the "
          "chi-square-like periodic power, the signed value for level, reversal and hysteresis); "
          "alpha shared by the {n} features that flag (the naming-only ones at the same "
          "alpha)")


# how each feature's healthy scores are distributed, for its prediction bound:
# ("chi2", k) a scaled chi-square with k degrees of freedom (the periodic power is one
# with 4 under white noise); ("abs", 1) the absolute value of a zero-mean normal (its
# square a scaled chi-square with 1); "log" a log-normal (the localised scan, a maximum,
# stays well away from 0)
NULLS: dict[str, tuple[str, int]] = {"periodic": ("chi2", 4), "level": ("abs", 1),
                                     "reversal": ("abs", 1), "hysteresis": ("abs", 1),
                                     "localised": ("log", 0),
                                     "takeup": ("log", 0), "turn": ("log", 0),
                                     "dwell": ("log", 0),
                                     "index": ("log", 0), "rattle": ("log", 0),
                                     "play": ("log", 0)}


def healthy_value(f: CycleFeatures, key: str) -> float:
    """The value of feature `key` that `spread_bound` models: the signed value for the
    two-sided scores (level, reversal, hysteresis), else the score."""
    if key == "level":
        return signed_level(f)
    if key == "reversal":
        return f.reversal_signed if math.isfinite(f.reversal_signed) else f.scores[key]
    if key == "hysteresis":
        return f.hysteresis_signed
    return f.scores[key]


def _transform(kind: str, v: np.ndarray) -> np.ndarray:
    if kind == "chi2":
        return np.cbrt(np.maximum(v, 0.0))      # Wilson-Hilferty: near normal
    if kind == "abs":
        return v
    return np.log(np.maximum(v, 1e-9))


def threshold_of(sp: Spread, alpha: float, null: tuple[str, int]) -> float:
    """The threshold of one feature from its spread (`spread.Spread`) on the transformed
    scale: the upper (1 - alpha) prediction bound of one cycle of a new run, back to the
    score's (two-sided, |value|, for the signed ones)."""
    kind = null[0]
    if kind == "abs":
        from scipy.special import stdtrit
        q = float(stdtrit(sp.dof, 1.0 - alpha / 2))
        return abs(sp.mean) + q * math.sqrt(sp.predictive)
    up = sp.upper(alpha)
    return max(up, 0.0) ** 3 if kind == "chi2" else math.exp(up)


def spread_bound(values: list[float], runs: list[int], alpha: float,
                 null: tuple[str, int]) -> tuple[float, Spread]:
    """The threshold of one feature of one load from its held-out healthy values
    (`healthy_value`) and their runs (`threshold_of`)."""
    v = np.asarray(values, float)
    ok = np.isfinite(v)
    if ok.sum() < 3:
        raise BenchError(f"a threshold needs at least 3 held-out healthy scores, got "
                         f"{int(ok.sum())}")
    sp = spread(_transform(null[0], v[ok]), list(np.asarray(runs)[ok]))
    return threshold_of(sp, alpha, null), sp


def bound(values: list[float], alpha: float, null: tuple[str, int]) -> float:
    """Upper (1 - alpha) prediction bound of one more healthy score, from m held-out ones:
    for a scaled chi-square with k dof, mean * F(1 - alpha; k, k m) (the ratio of a new
    value to the mean of m is F-distributed); for |normal|, sqrt(mean of squares *
    F(1 - alpha; 1, m)); else the log-normal Student-t bound."""
    from scipy.special import fdtri
    kind, k = null
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    m = len(v)
    if m < 3:
        raise BenchError(f"a threshold needs at least 3 held-out healthy scores, got {m}")
    if kind == "chi2":
        return float(v.mean() * fdtri(k, k * m, 1.0 - alpha))
    if kind == "abs":
        return float(math.sqrt(np.mean(v ** 2) * fdtri(1, m, 1.0 - alpha)))
    return prediction_bound(list(v), alpha)


def prediction_bound(values: list[float], alpha: float) -> float:
    """Upper (1 - alpha) Student-t prediction bound of one more value, on log scale."""
    from scipy.special import stdtrit  # Student-t quantile (scipy.stats is slow to import)
    v = np.log(np.maximum(np.asarray(values, float), 1e-9))
    v = v[np.isfinite(v)]
    m = len(v)
    if m < 3:
        raise BenchError(f"a threshold needs at least 3 held-out healthy scores, got {m}")
    t = float(stdtrit(m - 1, 1.0 - alpha))
    return float(math.exp(v.mean() + t * v.std(ddof=1) * math.sqrt(1.0 + 1.0 / m)))


@dataclass
class Loro:
    """One load's leave-one-run-out healthy scores: each calibration run's cycles scored
    against the baseline of the other runs."""
    load: float
    runs: list[int]
    scores: dict[str, list[float]]
    values: dict[str, list[float]]         # `healthy_value` of each score
    of_run: list[int]
    zscores: list[float]


def loro(cycles: list[Cycle], lead_mm: float | None = None) -> Loro:
    """`Loro` of one load's healthy calibration cycles (two or more runs)."""
    runs = sorted({c.run for c in cycles})
    if len(runs) < 2:
        raise BenchError(f"load {cycles[0].load:g}: thresholds need at least two healthy "
                         f"calibration runs (one held out at a time), got run(s) {runs}")
    _check_folds(cycles, runs)
    out = Loro(cycles[0].load, runs, {k: [] for k in FEATURES}, {k: [] for k in FEATURES},
               [], [])
    for r in runs:
        lb = build_load([c for c in cycles if c.run != r])
        for c in cycles:
            if c.run == r:
                f = cycle_features(lb, c, lead_mm)
                if f.incomplete:          # a partial cycle gives no healthy score
                    continue
                out.of_run.append(r)
                out.zscores.append(zscore_score(lb, c))
                for k in FEATURES:
                    if k == PLAY:         # from the thresholds (`thresholds`)
                        continue
                    out.scores[k].append(f.scores[k])
                    out.values[k].append(healthy_value(f, k))
    return out


def thresholds(loros: dict[float, Loro], alpha: float = ALPHA) -> dict[float, Calibration]:
    """Per load the thresholds of its features from the loads' leave-one-run-out scores,
    the spreads within and between runs pooled over the loads (`spread.pooled`); a
    feature a load's cycles cannot give (periodic without the lead) gets none. BenchError
    for a threshold that is not finite (at an alpha so small that the bound overflows): a
    baseline never carries one (`baseline.threshold_problem`)."""
    usable = [k for k in FEATURES if k != PLAY and all(
        np.isfinite(lo.scores[k]).all() and lo.scores[k] for lo in loros.values())]
    per = alpha / max(len([k for k in usable if k not in NAMING_ONLY]), 1)
    thr: dict[float, dict[str, float]] = {ld: {} for ld in loros}
    spreads: dict[float, dict[str, Spread]] = {ld: {} for ld in loros}
    for k in usable:
        null = NULLS.get(k, ("log", 0))
        sps = pooled({ld: list(_transform(null[0], np.asarray(lo.values[k], float)))
                      for ld, lo in loros.items()}, {ld: lo.of_run for ld, lo in loros.items()})
        for ld, sp in sps.items():
            if sp.cycles < 3:
                raise BenchError(f"load {ld:g}: a threshold needs at least 3 held-out "
                                 f"healthy scores, got {sp.cycles}")
            spreads[ld][k] = sp
            thr[ld][k] = threshold_of(sp, per, null)
    if all(k in usable for k in PLAY_OF):
        _play(loros, thr, spreads, per)
    for ld, by in thr.items():      # never an infinite threshold: it flags no cycle
        for k, v in by.items():
            if not math.isfinite(v):
                raise BenchError(f"load {ld:g}: the {k} threshold at alpha {alpha:g} is "
                                 f"{v:g}, not a finite number (the held-out healthy "
                                 "scores give no bound that far in their tail)")
    return {ld: Calibration(ld, lo.runs, thr[ld], lo.scores, alpha, lo.of_run, spreads[ld],
                            prediction_bound(lo.zscores, alpha)) for ld, lo in loros.items()}


def _play(loros: dict[float, Loro], thr: dict[float, dict[str, float]],
          spreads: dict[float, dict[str, Spread]], per: float) -> None:
    """The combined play's threshold (`play.play_score`), in place: its held-out
    healthy values from each cycle's scores against the thresholds just set, then its
    bound as any log-normal feature's (the spreads pooled over the loads)."""
    for ld, lo in loros.items():
        lo.scores[PLAY] = lo.values[PLAY] = [
            play_score({k: lo.scores[k][i] for k in PLAY_OF}, thr[ld])
            for i in range(len(lo.of_run))]
    null = NULLS[PLAY]
    sps = pooled({ld: list(_transform(null[0], np.asarray(lo.values[PLAY], float)))
                  for ld, lo in loros.items()}, {ld: lo.of_run for ld, lo in loros.items()})
    for ld, sp in sps.items():
        if sp.cycles >= 3:
            spreads[ld][PLAY] = sp
            thr[ld][PLAY] = threshold_of(sp, per, null)


def calibrate(cycles: list[Cycle], alpha: float = ALPHA, lead_mm: float | None = None
              ) -> Calibration:
    """Thresholds of one load from its healthy calibration cycles alone (two or more
    runs; `calibrate_loads` pools several loads' spreads)."""
    lo = loro(cycles, lead_mm)
    return thresholds({lo.load: lo}, alpha)[lo.load]


def _check_folds(cycles: list[Cycle], runs: list[int]) -> None:
    """BenchError when a leave-one-run-out fold leaves fewer cycles than a baseline needs,
    with the real counts (cycles per run), not the fold's alone."""
    per = {r: sum(c.run == r for c in cycles) for r in runs}
    for r in runs:
        rest = len(cycles) - per[r]
        if rest < MIN_CYCLES:
            c = cycles[0]
            load = f"{c.load:g} {c.load_unit}".strip()
            others = ",".join(str(x) for x in runs if x != r)
            raise BenchError(
                f"load {load}: the thresholds are set leave-one-run-out, and with run {r} "
                f"held out the other run(s) ({others}) have {rest} healthy cycle(s), fewer "
                f"than the {MIN_CYCLES} a baseline needs (cycles per run: "
                + ", ".join(f"run {k}: {n}" for k, n in per.items()) + ")")


def check_runs(cal: list[Cycle], hold: list[Cycle], calibrate_runs: list[int],
               holdout_runs: list[int], have: set[int], where: str) -> None:
    """BenchError naming the run list (calibration, held-out, or both) of which `where`
    has no cycle; `have`: the runs it has."""
    empty = [f"the {what} runs {','.join(map(str, runs))} ({flag})"
             for what, flag, runs, got in (("calibration", "--calibrate-runs", calibrate_runs,
                                            cal),
                                           ("held-out", "--holdout-runs", holdout_runs, hold))
             if not got]
    if empty:
        raise BenchError(f"{where}: no cycle of {' nor of '.join(empty)}; the healthy "
                         f"cycles read are of run(s) {','.join(map(str, sorted(have)))}")


def calibrate_loads(cycles: list[Cycle], alpha: float = ALPHA, lead_mm: float | None = None
                    ) -> dict[float, Calibration]:
    """The thresholds of every load of the healthy calibration cycles, in load order,
    the spreads between and within runs pooled over the loads (`thresholds`)."""
    return thresholds({load: loro([c for c in cycles if c.load == load], lead_mm)
                       for load in sorted({c.load for c in cycles})}, alpha)


def cross_validate(cycles: list[Cycle], k: int, alpha: float = ALPHA,
                   lead_mm: float | None = None, max_splits: int = 20,
                   faults: dict[str, list[Cycle]] | None = None) -> dict[str, Any]:
    """The healthy false-alarm rate, cross-validated: every choice of `k` of the healthy
    runs (at most `max_splits`, a fixed-seed sample beyond) calibrates a baseline and its
    thresholds as `calibrate` does, and the cycles of the other runs are judged against
    them. With ten held-out cycles a rate of 0 / 10 still allows a true rate of 26 %;
    over all the splits of four runs (six for k = 2) every healthy cycle is judged
    several times, by thresholds that never saw its run. `faults` (condition -> its
    cycles at this load): each split also judges them, so the detection rate of every
    condition is given for every choice of calibration runs (`split_rates`), not for one.
    A measurement only: no threshold is set from it. Empty when there are fewer than
    k + 1 runs. In this process; `split_jobs`, `calibrate_split`, `judge_splits` and
    `summarise_splits` are its parts for a caller that spreads the work over workers
    (`bench rig study`)."""
    jobs = split_jobs(cycles, k, alpha, lead_mm, max_splits)
    if not jobs:
        return {}
    load = cycles[0].load
    splits = [of_load(calibrate_split(j), load) for j in jobs]
    return summarise_splits(cycles, k, splits, {cond: judge_splits((splits, cs))
                                                for cond, cs in (faults or {}).items()})


def of_load(split: dict[str, Any], load: float) -> dict[str, Any]:
    """One load's part of a `calibrate_split` result, with the split's runs."""
    return {"calibrate_runs": split["calibrate_runs"], **split["loads"][load]}


def splits_of(runs: list[int], k: int, max_splits: int = 20) -> list[tuple[int, ...]]:
    """Every choice of `k` of `runs` (at most `max_splits`, a fixed-seed sample beyond);
    none when fewer than k + 1 runs leave no run to judge."""
    import itertools
    if k < 2 or len(runs) <= k:
        return []
    splits = list(itertools.combinations(runs, k))
    if len(splits) > max_splits:
        rng = np.random.default_rng(0)
        pick = sorted(rng.choice(len(splits), max_splits, replace=False))
        splits = [splits[i] for i in pick]
    return splits


def split_jobs(cycles: list[Cycle], k: int, alpha: float = ALPHA,
               lead_mm: float | None = None, max_splits: int = 20
               ) -> list[tuple[Any, ...]]:
    """One `calibrate_split` job per choice of `k` healthy runs (`cross_validate`); none
    when there are fewer than k + 1 runs."""
    return [(cycles, cal_runs, alpha, lead_mm)
            for cal_runs in splits_of(sorted({c.run for c in cycles}), k, max_splits)]


def calibrate_split(job: tuple[Any, ...]) -> dict[str, Any]:
    """One split of `cross_validate` (a worker job): for every load of the healthy
    `cycles`, the calibration runs' baseline and thresholds (the spreads pooled over the
    loads, `calibrate_loads`), computed once per split and kept for `judge_splits`, and
    the other healthy runs' cycles judged against them (`loads`: load -> that)."""
    cycles, cal_runs, alpha, lead_mm = job
    mine = [c for c in cycles if c.run in cal_runs]
    cals = calibrate_loads(mine, alpha, lead_mm)
    loads: dict[float, dict[str, Any]] = {}
    for load, cal in cals.items():
        part = {"baseline": build_load([c for c in mine if c.load == load]),
                "thresholds": cal.thresholds, "zscore_threshold": cal.zscore_threshold,
                "lead_mm": lead_mm}
        part.update(_count(part, [c for c in cycles
                                  if c.load == load and c.run not in cal_runs]))
        loads[load] = part
    return {"calibrate_runs": list(cal_runs), "loads": loads}


def judge_splits(job: tuple[list[dict[str, Any]], list[Cycle]]) -> list[dict[str, Any]]:
    """One fault condition's cycles judged under every split (a worker job): the splits'
    `calibrate_split` results and the cycles; counts per split."""
    splits, cycles = job
    return [{"calibrate_runs": s["calibrate_runs"], **_count(s, cycles)} for s in splits]


def pooled_counts(counts: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts of `_count` added over the splits: judged, flagged, the z-score's flags and
    the fault families named."""
    out: dict[str, Any] = {"judged": 0, "flagged": 0, "zscore_flagged": 0, "faults": {}}
    for c in counts:
        for k in ("judged", "flagged", "zscore_flagged"):
            out[k] += c.get(k, 0)
        for k, v in c.get("faults", {}).items():
            out["faults"][k] = out["faults"].get(k, 0) + v
    return out


def _count(split: dict[str, Any], cycles: list[Cycle]) -> dict[str, Any]:
    """`cycles` judged against one split's baseline and thresholds: judged, flagged and
    the effects named (incomplete cycles are not judged)."""
    n = f = z = 0
    effects: dict[str, int] = {}
    faults: dict[str, int] = {}
    for c in cycles:
        feat = cycle_features(split["baseline"], c, split["lead_mm"])
        if feat.incomplete:
            continue
        j = assess(feat, split["thresholds"])
        n += 1
        f += int(j.flagged)
        z += int(zscore_score(split["baseline"], c) > split.get("zscore_threshold", np.inf))
        if j.flagged:
            effects[j.effect] = effects.get(j.effect, 0) + 1
            faults[j.fault] = faults.get(j.fault, 0) + 1
    return {"judged": n, "flagged": f, "effects": effects, "faults": faults,
            "zscore_flagged": z}


def summarise_splits(cycles: list[Cycle], k: int, splits: list[dict[str, Any]],
                     faults: dict[str, list[dict[str, Any]]] | None = None
                     ) -> dict[str, Any]:
    """`cross_validate`'s result from its splits (`calibrate_split`) and each fault
    condition's counts under them (`judge_splits`)."""
    flagged = sum(r["flagged"] for r in splits)
    judged = sum(r["judged"] for r in splits)
    effects: dict[str, int] = {}
    for r in splits:
        for e, n in r["effects"].items():
            effects[e] = effects.get(e, 0) + n
    per_split = [{"calibrate_runs": r["calibrate_runs"], "judged": r["judged"],
                  "flagged": r["flagged"]} for r in splits]
    zf = sum(r.get("zscore_flagged", 0) for r in splits)
    out: dict[str, Any] = {
        "k": k, "runs": sorted({c.run for c in cycles}), "splits": len(splits),
        "judged": judged, "flagged": flagged,
        "rate": flagged / judged if judged else float("nan"), "effects": effects,
        "per_split": per_split, "rate_95": clopper_pearson(flagged, judged),
        "zscore_flagged": zf, "zscore_rate": zf / judged if judged else float("nan"),
        "zscore_rate_95": clopper_pearson(zf, judged)}
    if faults:
        out["faults"] = {cond: split_rates(counts) for cond, counts in faults.items()}
    return out


def split_rates(splits: list[dict[str, Any]]) -> dict[str, Any]:
    """A fault condition's detection rate under every split (`judge_splits`' counts):
    each split's counts and the least, median and largest of their rates."""
    rates = [c["flagged"] / c["judged"] for c in splits if c["judged"]]
    nan = float("nan")
    return {"per_split": [{"calibrate_runs": c["calibrate_runs"], "judged": c["judged"],
                           "flagged": c["flagged"]} for c in splits],
            "pooled": pooled_counts(splits),
            "min": min(rates) if rates else nan,
            "median": float(np.median(rates)) if rates else nan,
            "max": max(rates) if rates else nan}


def clopper_pearson(k: int, n: int, conf: float = 0.95) -> list[float]:
    """The exact two-sided `conf` interval of a rate of k in n (Clopper-Pearson)."""
    from scipy.special import betaincinv
    if n <= 0:
        return [float("nan"), float("nan")]
    a = (1.0 - conf) / 2
    lo = 0.0 if k == 0 else float(betaincinv(k, n - k + 1, a))
    hi = 1.0 if k == n else float(betaincinv(k + 1, n - k, 1 - a))
    return [lo, hi]


def zscore_score(lb: LoadBaseline, cycle: Cycle) -> float:
    """The plain reference: the cycle's largest |per-sample z-score| of the current
    against the healthy mean at the same aligned sample, over all phases."""
    res = residuals(lb, cycle, "current_a")
    vals = [float(np.max(np.abs(z))) for z, _ in res.values() if len(z)]
    return max(vals) if vals else float("nan")


def matched_threshold(healthy_scores: list[float], n_flagged: int) -> float:
    """The z-score threshold that flags `n_flagged` of the held-out healthy cycles (the
    bench detector's count): between the n-th and (n+1)-th largest score."""
    s = sorted((x for x in healthy_scores if math.isfinite(x)), reverse=True)
    if not s:
        return float("nan")
    if n_flagged >= len(s):
        return s[-1] * 0.999
    return s[n_flagged]          # flagged: score > threshold


def rates(features: list[CycleFeatures], thresholds: dict[str, float]) -> dict[str, Any]:
    """Detection (or false-alarm) rate of a condition, the effects named and where the
    located ones are (`located` cycles; median and interquartile range of the position in
    mm; `features.location`); incomplete cycles are not judged (`not_judged`, outside the
    rate)."""
    skipped = [f for f in features if f.incomplete]
    features = [f for f in features if not f.incomplete]
    n = len(features)
    flagged = 0
    effects: dict[str, int] = {}
    locs: list[float] = []
    outs: list[float] = []
    ins: list[float] = []
    faults: dict[str, int] = {}
    for f in features:
        j = assess(f, thresholds)
        if not j.flagged:
            continue
        effect = j.effect
        flagged += 1
        effects[effect] = effects.get(effect, 0) + 1
        faults[j.fault] = faults.get(j.fault, 0) + 1
        where = location(f, effect, thresholds)
        if where is not None:
            locs.append(where)
            outs.append(f.out_mm)
            ins.append(f.in_mm)
    out: dict[str, Any] = {"cycles": n, "flagged": flagged,
                           "rate": flagged / n if n else float("nan"), "effects": effects,
                           "faults": faults, "rate_95": clopper_pearson(flagged, n),
                           "located": len(locs), "not_judged": len(skipped)}
    out.update(_where(locs, "position"))
    out.update(_where(outs, "out"))
    out.update(_where(ins, "in"))
    return out


def _where(vals: list[float], key: str) -> dict[str, float]:
    v = np.asarray([x for x in vals if math.isfinite(x)], float)
    if not len(v):
        return {f"{key}_mm": float("nan"), f"{key}_iqr_mm": float("nan")}
    q1, q2, q3 = np.percentile(v, [25, 50, 75])
    return {f"{key}_mm": float(q2), f"{key}_iqr_mm": float(q3 - q1)}


def naming_summary(counts: dict[str, int], expected: str | None) -> dict[str, Any]:
    """Flagged cycles per physics name (`naming.FAULTS`) and the share named the
    `expected` family, with its exact 95 % interval, of one condition."""
    n = sum(counts.values())
    k = counts.get(expected, 0) if expected else 0
    return {"faults": dict(counts), "expected": expected, "flagged": n,
            "correct": k if expected else None,
            "rate": (k / n if n else float("nan")) if expected else None,
            "rate_95": clopper_pearson(k, n) if expected and n else None}
