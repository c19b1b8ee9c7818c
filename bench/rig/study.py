"""The study of a rig's development set (`bench rig study DIR`): baseline and thresholds
from the healthy calibration runs, then every other cycle scored, per condition and load:
false-alarm rate on the held-out healthy runs, detection rate per fault stage, the
effect named, where a localised effect lies, the plain z-score reference at the same
false-alarm rate, and the cost. The per-cycle work runs over `bench.workers.run_all`.
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
from bench.rig import population as P
from bench.rig.cycles import SUFFIXES, Cycle, condition_name, read_cycles, stage_number
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

    @property
    def loads(self) -> list[float]:
        return sorted(self.calibrations)

    @property
    def fault_conditions(self) -> list[str]:
        names = [c for c in self.results if c != self.healthy_condition]
        return sorted(names, key=lambda c: (stage_number(c) or 0, c))


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
    if not d.is_dir():
        raise BenchError(f"no such directory: {d}")
    files = sorted(p for p in d.iterdir()
                   if p.is_file() and p.name.lower().endswith(SUFFIXES))
    if not files:
        raise BenchError(f"{d}: no table ({', '.join(SUFFIXES)}) in the directory")
    return files


def run_study(directory: str | Path, calibrate_runs: list[int], holdout_runs: list[int],
              healthy: str = "normal*", workers: int | None = None, alpha: float = P.ALPHA,
              progress: bool = True, conditions: list[str] | None = None,
              lead_mm: float | None = None, scheduler: str | None = None) -> Study:
    """Baseline and thresholds from the healthy table's `calibrate_runs`, then the
    held-out healthy runs and every fault table scored (per condition a `run_all`)."""
    from bench.workers import run_all
    if set(calibrate_runs) & set(holdout_runs):
        raise BenchError("the calibration and held-out runs overlap: "
                         f"{sorted(set(calibrate_runs) & set(holdout_runs))}")
    files = table_files(directory)
    healthy_files = [p for p in files if fnmatch.fnmatch(p.name, healthy + "*")]
    if len(healthy_files) != 1:
        raise BenchError(f"{directory}: expected one healthy table matching {healthy!r}, "
                         f"found {len(healthy_files)}")
    hname = condition_name(healthy_files[0])
    hcycles = read_cycles(healthy_files[0])
    cal = [c for c in hcycles if c.run in calibrate_runs]
    hold = [c for c in hcycles if c.run in holdout_runs]
    if not cal or not hold:
        raise BenchError(f"{healthy_files[0]}: no cycle of the calibration runs "
                         f"{calibrate_runs} or of the held-out runs {holdout_runs}")
    base = B.build(cal, [healthy_files[0].name])
    base.lead_mm = lead_mm
    cals = {}
    for load in sorted({c.load for c in cal}):
        cals[load] = P.calibrate([c for c in cal if c.load == load], alpha, lead_mm)
    base.thresholds = {f"{k:g}": v.to_json() for k, v in cals.items()}
    study = Study(base, cals, sorted(holdout_runs), {}, hname)
    todo: list[tuple[str, list[Cycle]]] = [(hname, hold)]
    for p in files:
        name = condition_name(p)
        if p in healthy_files or (conditions and name not in conditions):
            continue
        todo.append((name, read_cycles(p)))
    for name, cycles in todo:
        jobs = [(base.for_load(c.load), c, lead_mm) for c in cycles if c.load in cals]
        t0 = time.perf_counter()
        res = run_all(score_cycle, jobs, workers=workers, progress=progress, desc=name,
                      unit="cycle", scheduler=scheduler)
        study.wall_s[name] = time.perf_counter() - t0
        per: dict[float, list[CycleResult]] = {}
        for (lb, _, _), r in zip(jobs, res, strict=True):
            per.setdefault(lb.load, []).append(r)
        study.results[name] = per
    study.summary = summarise(study)
    return study


def summarise(study: Study) -> dict[str, Any]:
    """The numbers of the study: per load, false alarms, detection per stage, locations,
    z-score reference, cost."""
    out: dict[str, Any] = {"baseline": study.baseline.describe(),
                           "calibrate_runs": study.calibrations[study.loads[0]].runs,
                           "holdout_runs": study.holdout_runs, "loads": {}}
    for load in study.loads:
        thr = study.calibrations[load].thresholds
        hold = study.results[study.healthy_condition].get(load, [])
        fa = P.rates([r.features for r in hold], thr)
        zthr = P.matched_threshold([r.zscore for r in hold], fa["flagged"])
        fa["zscore_rate"] = _zrate(hold, zthr)
        row: dict[str, Any] = {"thresholds": thr, "zscore_threshold": zthr,
                               "holdout": fa, "stages": {}}
        for cond in study.fault_conditions:
            rs = study.results[cond].get(load, [])
            if not rs:
                continue
            d = P.rates([r.features for r in rs], thr)
            d["zscore_rate"] = _zrate(rs, zthr)
            row["stages"][cond] = d
        out["loads"][f"{load:g}"] = row
    secs = [r.seconds for c in study.results.values() for v in c.values() for r in v]
    out["cost"] = {"cycle_s_median": float(np.median(secs)), "cycle_s_max": float(max(secs)),
                   "cycles": len(secs), "wall_s": study.wall_s,
                   "cycles_per_condition": {k: sum(len(v) for v in c.values())
                                            for k, c in study.results.items()}}
    return out


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
