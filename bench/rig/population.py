"""Populations of runs (issue 11): thresholds from the spread of held-out healthy runs, and
a detection rate and a false-alarm rate per condition instead of a single verdict.

Thresholds (`calibrate`): with the calibration runs of one load (e.g. runs 1-2), each run
in turn is held out, a baseline is built from the others, and the held-out run's cycles
are scored; so every calibration score is that of a cycle its baseline did not see
(leave-one-run-out; run-to-run differences are in the scores). The threshold of a
feature is the upper (1 - alpha / n_features) prediction bound of one more healthy score
(`bound`), alpha the false-alarm rate aimed at (0.05), shared by the features
(Bonferroni): an F bound for the chi-square-like scores (periodic power; level and
reversal squared), a Student-t bound of the log-scores for the maxima (the localised and
dwell scans, the largest phase-index |z|). (The
first version used the log-normal bound for every feature; it gave thresholds of 20-35
for chi-square scores near 0, and was replaced after the first study: docs/real-data.md.) The
thresholds come from healthy calibration runs only, never from a fault's cycles.

The reference detector the issue asks for (`zscore_score`): a plain per-sample z-score
of the current against the healthy mean at the same aligned sample (all phases), the
cycle's score its largest |z|; its threshold is set so that it flags the same number of
held-out healthy cycles as the bench's detector (`matched_threshold`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig.baseline import MIN_CYCLES, LoadBaseline, build_load, residuals
from bench.rig.cycles import Cycle
from bench.rig.features import FEATURES, CycleFeatures, cycle_features, judge, location

ALPHA = 0.05


@dataclass
class Calibration:
    """Thresholds of one load and the held-out healthy scores they came from."""
    load: float
    runs: list[int]
    thresholds: dict[str, float]
    scores: dict[str, list[float]]        # leave-one-run-out healthy scores per feature
    alpha: float

    def to_json(self) -> dict[str, Any]:
        return {"load": self.load, "runs": self.runs, "thresholds": self.thresholds,
                "loro_scores": self.scores, "alpha": self.alpha,
                "method": "leave-one-run-out over the calibration runs; upper prediction "
                          "bound per feature (F for chi-square-like scores, Student-t of "
                          "the log for the scans and the index maximum), alpha shared by "
                          f"{len(self.thresholds)} features",
                "nulls": {k: list(NULLS.get(k, ("log", 0))) for k in self.thresholds}}


# how each feature's healthy scores are distributed, for its prediction bound:
# ("chi2", k) a scaled chi-square with k degrees of freedom (the periodic power is one
# with 4 under white noise); ("abs", 1) the absolute value of a zero-mean normal (its
# square a scaled chi-square with 1); "log" a log-normal (the localised scan, a maximum,
# stays well away from 0)
NULLS: dict[str, tuple[str, int]] = {"periodic": ("chi2", 4), "level": ("abs", 1),
                                     "reversal": ("abs", 1), "localised": ("log", 0),
                                     "dwell": ("log", 0), "index": ("log", 0)}


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


def calibrate(cycles: list[Cycle], alpha: float = ALPHA, lead_mm: float | None = None
              ) -> Calibration:
    """Thresholds of one load from its healthy calibration cycles (two or more runs); a
    feature the cycles cannot give (periodic without the lead) gets none."""
    runs = sorted({c.run for c in cycles})
    if len(runs) < 2:
        raise BenchError(f"load {cycles[0].load:g}: thresholds need at least two healthy "
                         f"calibration runs (one held out at a time), got run(s) {runs}")
    _check_folds(cycles, runs)
    scores: dict[str, list[float]] = {k: [] for k in FEATURES}
    for r in runs:
        lb = build_load([c for c in cycles if c.run != r])
        for c in cycles:
            if c.run == r:
                f = cycle_features(lb, c, lead_mm)
                if f.incomplete:          # a partial cycle gives no healthy score
                    continue
                for k in FEATURES:
                    scores[k].append(f.scores[k])
    usable = {k: v for k, v in scores.items() if np.isfinite(v).all()}
    per = alpha / len(usable)
    thr = {k: bound(v, per, NULLS.get(k, ("log", 0))) for k, v in usable.items()}
    return Calibration(cycles[0].load, runs, thr, scores, alpha)


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
    """`calibrate` for each load of the healthy calibration cycles, in load order."""
    return {load: calibrate([c for c in cycles if c.load == load], alpha, lead_mm)
            for load in sorted({c.load for c in cycles})}


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
    splits = [calibrate_split(j) for j in jobs]
    return summarise_splits(cycles, k, splits, {cond: judge_splits((splits, cs))
                                                for cond, cs in (faults or {}).items()})


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
    """One split of `cross_validate` (a worker job): the calibration runs' baseline and
    thresholds, computed once per split and kept for `judge_splits`, and the other
    healthy runs' cycles judged against them."""
    cycles, cal_runs, alpha, lead_mm = job
    mine = [c for c in cycles if c.run in cal_runs]
    out = {"calibrate_runs": list(cal_runs), "baseline": build_load(mine),
           "thresholds": calibrate(mine, alpha, lead_mm).thresholds, "lead_mm": lead_mm}
    out.update(_count(out, [c for c in cycles if c.run not in cal_runs]))
    return out


def judge_splits(job: tuple[list[dict[str, Any]], list[Cycle]]) -> list[dict[str, Any]]:
    """One fault condition's cycles judged under every split (a worker job): the splits'
    `calibrate_split` results and the cycles; counts per split."""
    splits, cycles = job
    return [{"calibrate_runs": s["calibrate_runs"], **_count(s, cycles)} for s in splits]


def _count(split: dict[str, Any], cycles: list[Cycle]) -> dict[str, Any]:
    """`cycles` judged against one split's baseline and thresholds: judged, flagged and
    the effects named (incomplete cycles are not judged)."""
    n = f = 0
    effects: dict[str, int] = {}
    for c in cycles:
        feat = cycle_features(split["baseline"], c, split["lead_mm"])
        if feat.incomplete:
            continue
        hit, effect, _ = judge(feat, split["thresholds"])
        n += 1
        f += int(hit)
        if hit:
            effects[effect] = effects.get(effect, 0) + 1
    return {"judged": n, "flagged": f, "effects": effects}


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
    out: dict[str, Any] = {
        "k": k, "runs": sorted({c.run for c in cycles}), "splits": len(splits),
        "judged": judged, "flagged": flagged,
        "rate": flagged / judged if judged else float("nan"), "effects": effects,
        "per_split": per_split, "rate_95": clopper_pearson(flagged, judged)}
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
    for f in features:
        hit, effect, _ = judge(f, thresholds)
        if not hit:
            continue
        flagged += 1
        effects[effect] = effects.get(effect, 0) + 1
        where = location(f, effect, thresholds)
        if where is not None:
            locs.append(where)
            outs.append(f.out_mm)
            ins.append(f.in_mm)
    out: dict[str, Any] = {"cycles": n, "flagged": flagged,
                           "rate": flagged / n if n else float("nan"), "effects": effects,
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
