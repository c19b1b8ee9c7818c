"""The study of a rig's development set (`bench rig study DIR`): baseline and thresholds
from the healthy calibration runs, then every other cycle scored, per condition and load:
false-alarm rate on the held-out healthy runs, detection rate per fault stage, the
effect named, where a localised effect lies, the plain z-score reference at the same
false-alarm rate, and the cost. The per-cycle work runs over `bench.runtime.workers.run_all`.
"""

from __future__ import annotations

import fnmatch
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig import baseline as B
from bench.rig import naming
from bench.rig import population as P
from bench.rig.classify import table_label
from bench.rig.cycles import (
    SUFFIXES,
    Cycle,
    condition_family,
    condition_name,
    read_cycles,
    stage_number,
)
from bench.rig.features import CycleFeatures, cycle_features


@dataclass
class CycleResult:
    features: CycleFeatures
    zscore: float
    seconds: float
    z_out: np.ndarray
    z_in: np.ndarray
    pos_out: np.ndarray
    pos_in: np.ndarray


@dataclass
class Study:
    """Everything `bench rig study` measured."""
    baseline: B.Baseline
    calibrations: dict[float, P.Calibration]
    holdout_runs: list[int]
    results: dict[str, dict[float, list[CycleResult]]]    # condition -> load -> cycles
    healthy_condition: str
    wall_s: dict[str, float] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    unscored: list[str] = field(default_factory=list)     # cycles no threshold could judge
    cross_validation: dict[float, dict[str, Any]] = field(default_factory=dict)
    cross_validation_s: float = 0.0
    supervised: dict[str, Any] = field(default_factory=dict)   # `supervised.run`

    @property
    def loads(self) -> list[float]:
        return sorted(self.calibrations)

    @property
    def fault_conditions(self) -> list[str]:
        names = [c for c in self.results if c != self.healthy_condition]
        return sorted(names, key=condition_key)

    @property
    def by_stage(self) -> bool:
        """Every fault table is a numbered stage of one family (spalling1 ... spalling8,
        or spalling5_load40_runs1-2 alone)."""
        conds = self.fault_conditions
        return (len({condition_key(c)[0] for c in conds}) == 1
                and all(stage_number(c) is not None for c in conds))

    @property
    def stage_header(self) -> str:
        """The report's column of fault conditions: "stage" or "condition"."""
        return "stage" if self.by_stage else "condition"

    def condition_label(self, cond: str) -> str:
        """A stage's number where every fault table is one family's stage, else the
        table's name (backlash1_runs1-5 beside spalling1)."""
        n = stage_number(cond)
        return str(n) if self.by_stage and n is not None else cond


def condition_key(cond: str) -> tuple[str, int, str]:
    """Fault tables in order: by family (the name less its stage number), then stage."""
    return (condition_family(cond), stage_number(cond) or 0, cond)


CHUNK = 16
"""Cycles per Dask task (a cycle's features take about 2 ms; a task costs a few ms of
scheduling and the transfer of its load's baseline)."""


def score_cycle(job: tuple[B.LoadBaseline, Cycle, float | None]) -> CycleResult:
    """One cycle against its load's baseline (a worker job)."""
    lb, cycle, lead = job
    t0 = time.perf_counter()
    f = cycle_features(lb, cycle, lead)
    z = P.zscore_score(lb, cycle)
    dt = time.perf_counter() - t0
    res = B.residuals(lb, cycle, "current_a")
    empty = (np.zeros(0), np.zeros(0))
    zo, po = res.get("out", empty)
    zi, pi = res.get("in", empty)
    return CycleResult(f, z, dt, zo, zi, po, pi)


def table_files(directory: str | Path) -> list[Path]:
    d = Path(directory)
    if d.is_file():
        raise BenchError(f"{d}: a file, not a directory: give the folder of the rig's "
                         "tables (the healthy table(s) and the fault tables)")
    if not d.is_dir():
        raise BenchError(f"no such directory: {d}")
    files = sorted(p for p in d.iterdir()
                   if p.is_file() and p.name.lower().endswith(SUFFIXES))
    if not files:
        raise BenchError(f"{d}: no table ({', '.join(SUFFIXES)}) in the directory")
    return files


def healthy_cycles(paths: list[Path], lost: list[str] | None = None
                   ) -> tuple[str, list[Cycle]]:
    """The cycles of one or more healthy tables (e.g. runs 1-4 in one file, runs 5-10 in
    another), as one condition; a run of a load found in two tables is refused. Cycles
    that cannot be read are listed in `lost`."""
    seen: dict[tuple[float, int], str] = {}
    cycles: list[Cycle] = []
    for p in paths:
        mine = read_cycles(p, skipped=lost)
        for key in sorted({(c.load, c.run) for c in mine}):
            if key in seen:
                raise BenchError(f"run {key[1]} of load {key[0]:g} is in both {seen[key]} "
                                 f"and {p.name}: one healthy run per table")
            seen[key] = p.name
        cycles += mine
    if len(paths) == 1:
        return condition_name(paths[0]), cycles
    name = "+".join(condition_name(p) for p in paths)
    return name, cycles


def run_study(directory: str | Path, calibrate_runs: list[int], holdout_runs: list[int],
              healthy: str = "normal*", workers: int | None = None, alpha: float = P.ALPHA,
              progress: bool = True, conditions: list[str] | None = None,
              lead_mm: float | None = None, scheduler: str | None = None,
              model: str | None = None, supervised: bool = True) -> Study:
    """Baseline and thresholds from the healthy table's `calibrate_runs`, then the
    held-out healthy runs and every fault table scored (per condition a `run_all`)."""
    if set(calibrate_runs) & set(holdout_runs):
        raise BenchError("the calibration and held-out runs overlap: "
                         f"{sorted(set(calibrate_runs) & set(holdout_runs))}")
    files = table_files(directory)
    healthy_files = [p for p in files if fnmatch.fnmatch(p.name, healthy + "*")]
    if not healthy_files:
        raise BenchError(f"{directory}: no healthy table matching {healthy + '*'!r}")
    names = [condition_name(p) for p in files if p not in healthy_files]
    unknown = sorted(set(conditions or []) - set(names))
    if unknown:
        raise BenchError(f"--only {','.join(unknown)}: no such fault table in {directory} "
                         f"(it has: {', '.join(names) or 'none'})")
    lost: list[str] = []
    hname, hcycles = healthy_cycles(healthy_files, lost)
    cal = [c for c in hcycles if c.run in calibrate_runs]
    hold = [c for c in hcycles if c.run in holdout_runs]
    P.check_runs(cal, hold, calibrate_runs, holdout_runs, {c.run for c in hcycles},
                 ", ".join(p.name for p in healthy_files))
    base = B.build(cal, [p.name for p in healthy_files])
    base.lead_mm = lead_mm
    cals = P.calibrate_loads(cal, alpha, lead_mm)
    base.thresholds = {f"{k:g}": v.to_json() for k, v in cals.items()}
    study = Study(base, cals, sorted(holdout_runs), {}, hname)
    idle = sorted({c.run for c in hcycles} - set(calibrate_runs) - set(holdout_runs))
    if idle:
        study.unscored.append(f"{hname}: healthy run(s) {','.join(map(str, idle))} neither "
                              "calibrate nor are held out (--holdout-runs)")
    todo: list[tuple[str, list[Cycle]]] = [(hname, hold)]
    for p in files:
        name = condition_name(p)
        if p in healthy_files or (conditions and name not in conditions):
            continue
        todo.append((name, read_cycles(p, skipped=lost)))
    study.unscored[:0] = lost               # cycles not read, before what was not scored
    _score(study, todo, base, cals, lead_mm, workers, progress, scheduler)
    healthy_runs = sorted(set(calibrate_runs) | set(holdout_runs))
    _cross_validate(study, [c for c in hcycles if c.run in healthy_runs],
                    [(n, cs) for n, cs in todo if n != hname], len(calibrate_runs), alpha,
                    lead_mm, workers, progress, scheduler)
    if supervised or model:
        from bench.rig.supervised import run as run_supervised
        todo_all = [(hname, [c for c in hcycles if c.run in healthy_runs]),
                    *[(n, cs) for n, cs in todo if n != hname]]
        study.supervised = run_supervised(todo_all, healthy.rstrip("*"), lead_mm, model,
                                          workers, progress, scheduler, supervised)
    study.summary = summarise(study)
    return study


def _score(study: Study, todo: list[tuple[str, list[Cycle]]], base: B.Baseline,
           cals: dict[float, P.Calibration], lead_mm: float | None, workers: int | None,
           progress: bool, scheduler: str | None) -> None:
    """Every condition's cycles scored over `run_all`, per load; cycles at a load without
    thresholds listed in `study.unscored`."""
    from bench.runtime.workers import run_all
    for name, cycles in todo:
        jobs = [(base.for_load(c.load), c, lead_mm) for c in cycles if c.load in cals]
        skipped = sorted({c.load for c in cycles if c.load not in cals})
        for load in skipped:
            n = sum(c.load == load for c in cycles)
            study.unscored.append(f"{name}: {n} cycle(s) at load {load:g} not scored "
                                  "(no healthy calibration run at that load)")
        if not jobs:
            continue
        t0 = time.perf_counter()
        res = run_all(score_cycle, jobs, workers=workers, progress=progress, desc=name,
                      unit="cycle", scheduler=scheduler, chunk=CHUNK)
        study.wall_s[name] = time.perf_counter() - t0
        per: dict[float, list[CycleResult]] = {}
        for (lb, _, _), r in zip(jobs, res, strict=True):
            per.setdefault(lb.load, []).append(r)
        study.results[name] = per


def _cross_validate(study: Study, healthy: list[Cycle], faults: list[tuple[str, list[Cycle]]],
                    k: int, alpha: float, lead_mm: float | None, workers: int | None,
                    progress: bool, scheduler: str | None) -> None:
    """`population.cross_validate` of every load over `run_all`: each split's baseline
    and thresholds once (with the held-out healthy runs judged), then each fault
    condition judged under every split of its load: the healthy false-alarm rate and
    every fault condition's detection rate under every choice of `k` healthy
    calibration runs."""
    from bench.runtime.workers import run_all
    t0 = time.perf_counter()
    mine = {load: [c for c in healthy if c.load == load] for load in study.loads}
    jobs = P.split_jobs([c for c in healthy if c.load in mine], k, alpha, lead_mm)
    done = run_all(P.calibrate_split, jobs, workers=workers, progress=progress,
                   desc="cross-validation", unit="split", scheduler=scheduler
                   ) if jobs else []
    splits = {load: [P.of_load(d, load) for d in done if load in d["loads"]]
              for load in study.loads}
    keys = [(load, name, [c for c in cs if c.load == load]) for load in study.loads
            if splits[load] for name, cs in faults]
    keys = [(load, name, cs) for load, name, cs in keys if cs]
    counts = run_all(P.judge_splits, [(splits[load], cs) for load, _, cs in keys],
                     workers=workers, progress=progress, desc="fault tables by split",
                     unit="condition", scheduler=scheduler) if keys else []
    for load in study.loads:
        fl = {name: n for (ld, name, _), n in zip(keys, counts, strict=True) if ld == load}
        study.cross_validation[load] = (P.summarise_splits(mine[load], k, splits[load], fl)
                                        if splits[load] else {})
    study.cross_validation_s = time.perf_counter() - t0


def summarise(study: Study) -> dict[str, Any]:
    """The numbers of the study: per load, false alarms, detection per stage, locations,
    z-score reference, cost."""
    out: dict[str, Any] = {"baseline": study.baseline.describe(),
                           "calibrate_runs": study.calibrations[study.loads[0]].runs,
                           "holdout_runs": study.holdout_runs, "loads": {}}
    for load in study.loads:
        cal = study.calibrations[load]
        thr = cal.thresholds
        hold = study.results[study.healthy_condition].get(load, [])
        fa = P.rates([r.features for r in hold], thr)
        zthr = P.matched_threshold([r.zscore for r in hold], fa["flagged"])
        fa["zscore_rate"] = _zrate(hold, zthr)
        fa.update(_zcal(hold, cal.zscore_threshold))
        row: dict[str, Any] = {"thresholds": thr, "zscore_threshold": zthr,
                               "zscore_calibrated_threshold": cal.zscore_threshold,
                               "provisional": cal.provisional,
                               "holdout": fa, "stages": {},
                               "cross_validation": study.cross_validation.get(load, {})}
        for cond in study.fault_conditions:
            rs = study.results[cond].get(load, [])
            if not rs:
                continue
            d = P.rates([r.features for r in rs], thr)
            d["zscore_rate"] = _zrate(rs, zthr)
            d.update(_zcal(rs, cal.zscore_threshold))
            d["naming"] = P.naming_summary(d["faults"], naming.expected_fault(
                table_label(cond)))
            row["stages"][cond] = d
        out["loads"][f"{load:g}"] = row
    out["supervised"] = study.supervised
    out["goals"] = goals(out)
    out["unscored"] = list(study.unscored)
    out["fault_tables_scored"] = list(study.fault_conditions)    # [] : healthy runs only
    secs = [r.seconds for c in study.results.values() for v in c.values() for r in v]
    out["cost"] = {"cycle_s_median": float(np.median(secs)), "cycle_s_max": float(max(secs)),
                   "cycles": len(secs), "wall_s": study.wall_s,
                   "cross_validation_s": study.cross_validation_s,
                   "cycles_per_condition": {k: sum(len(v) for v in c.values())
                                            for k, c in study.results.items()}}
    return out


def _zcal(rs: list[CycleResult], thr: float) -> dict[str, Any]:
    """The plain z-score with its own threshold from the calibration runs: cycles flagged
    and the rate with its interval."""
    ok = [r for r in rs if not r.features.incomplete]
    k = sum(r.zscore > thr for r in ok) if math.isfinite(thr) else 0
    return {"zscore_cal_flagged": k, "zscore_cal_rate": k / len(ok) if ok else float("nan"),
            "zscore_cal_rate_95": P.clopper_pearson(k, len(ok))}


def _zrate(rs: list[CycleResult], thr: float) -> float:
    if not rs or not math.isfinite(thr):
        return float("nan")
    return sum(r.zscore > thr for r in rs) / len(rs)


def mean_profile(rs: list[CycleResult], stroke: str) -> tuple[np.ndarray, np.ndarray]:
    """Mean current residual (z) and mean measured position per aligned sample."""
    zs = [r.z_out if stroke == "out" else r.z_in for r in rs]
    ps = [r.pos_out if stroke == "out" else r.pos_in for r in rs]
    m = min((len(z) for z in zs), default=0)
    if not m:
        return np.zeros(0), np.zeros(0)
    return (np.mean([z[:m] for z in zs], axis=0), np.mean([p[:m] for p in ps], axis=0))


def goals(sm: dict[str, Any]) -> dict[str, Any]:
    """The study's rates against the goals, every one on runs no threshold or rule used:
    per load the healthy false-alarm rate cross-validated over the choices of
    calibration runs; the fault cycles detected and the physics name right, pooled over
    the splits (every fault table at every load, judged under every split); beside them
    the plain z-score's."""
    out: dict[str, Any] = {"false_alarms": {}, "detected": {}, "named": {}}
    det = {"judged": 0, "flagged": 0, "zscore_flagged": 0}
    fam_det: dict[str, list[int]] = {}
    named: dict[str, list[int]] = {}
    for load, row in sm["loads"].items():
        cv = row.get("cross_validation") or {}
        if cv:
            out["false_alarms"][load] = {k: cv[k] for k in (
                "flagged", "judged", "rate", "rate_95", "zscore_flagged", "zscore_rate",
                "zscore_rate_95") if k in cv}
        for cond, r in (cv.get("faults") or {}).items():
            p = r.get("pooled") or {}
            for k in det:
                det[k] += p.get(k, 0)
            exp = naming.expected_fault(table_label(cond))
            fd = fam_det.setdefault(exp or table_label(cond), [0, 0])
            fd[0] += p.get("flagged", 0)
            fd[1] += p.get("judged", 0)
            if exp:
                got = named.setdefault(exp, [0, 0])
                got[0] += p.get("faults", {}).get(exp, 0)
                got[1] += p.get("flagged", 0)
    n = det["judged"]
    out["detected"] = {**det, "rate": det["flagged"] / n if n else float("nan"),
                       "rate_95": P.clopper_pearson(det["flagged"], n),
                       "zscore_rate": det["zscore_flagged"] / n if n else float("nan"),
                       "per_family": {k: {"flagged": v[0], "judged": v[1],
                                          "rate": v[0] / v[1] if v[1] else float("nan"),
                                          "rate_95": P.clopper_pearson(v[0], v[1])}
                                      for k, v in sorted(fam_det.items())}}
    right = sum(v[0] for v in named.values())
    flagged = sum(v[1] for v in named.values())
    out["named"] = {"right": right, "flagged": flagged,
                    "rate": right / flagged if flagged else float("nan"),
                    "rate_95": P.clopper_pearson(right, flagged),
                    "per_family": {k: {"right": v[0], "flagged": v[1],
                                       "rate": v[0] / v[1] if v[1] else float("nan"),
                                       "rate_95": P.clopper_pearson(v[0], v[1])}
                                   for k, v in sorted(named.items())}}
    return out
