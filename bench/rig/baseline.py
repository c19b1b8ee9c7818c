"""The healthy baseline of a rig that no physics model fits (the fallback).

When no model of the family reaches the noise floor on healthy data (a stepper's load
angle, the rig's own friction law), the bench compares a log with the rig's own healthy
runs instead. The runs are aligned by set-point phase (`cycles.phases`: out-stroke,
dwell at the top, in-stroke, dwell at the bottom; direction is part of the phase) and,
for each load, the baseline keeps per phase and per aligned sample the mean and the
spread of each signal (motor current, position error, and the current less the cycle's median
dwell current: `standstill_current`), and per phase the mean and spread
of each phase index (mean, RMS and peak current; mean and peak position error; the mean
current of the acceleration, constant-speed and deceleration parts of a stroke).

Aligned sample k of a phase is the k-th logged sample after the phase starts: the rig's
set-point repeats from cycle to cycle, so sample k is at the same set-point position in
every cycle and nothing is interpolated. The spread of a sample is pooled over its
`POOL` neighbours (a per-sample standard deviation from ten cycles is itself uncertain by
about 25 %). A residual is standardised by that spread times sqrt(1 + 1/n), n the number
of baseline cycles, because the baseline mean is itself an estimate.

Every verdict against a baseline names it (`Baseline.describe`): the file, the source
tables, the runs, the loads and the number of cycles.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.gap.inputs import BASELINE_FORMAT
from bench.rig import kernels as K
from bench.rig.cycles import Cycle
from bench.rig.spread import MIN_RUNS, spread

SIGNALS = ("current_a", "position_error_mm", "current_ref_a")
POOL = 7                    # samples pooled into one sample's spread
MIN_CYCLES = 3              # cycles per load a baseline needs
FORMAT = BASELINE_FORMAT     # the file's format tag (bench.gap.inputs reads it too)


def signal(cycle: Cycle, name: str) -> np.ndarray:
    """A cycle's signal: the logged current, the position error, or the current referenced
    to the cycle's standstill (`current_ref_a`: less the median current of its dwells)."""
    if name == "current_a":
        return cycle.current_a
    if name == "current_ref_a":
        return cycle.current_a - standstill_current(cycle)
    return cycle.position_error_mm


def _dwell_median(cycle: Cycle, column: str, key: str) -> float:
    """The median of the cycle's `column` over its dwells (0 without a dwell), memoised
    as `key` on the cycle."""
    def median() -> float:
        values = getattr(cycle, column)
        dwell = [values[s.start:s.stop] for s in cycle.segments() if s.direction == 0 and len(s)]
        return float(K.median(np.asarray(np.concatenate(dwell), np.float64))) if dwell \
            else 0.0
    return float(cycle.memo(key, median))


def standstill_current(cycle: Cycle) -> float:
    """The median current of the cycle's dwells (0 for a cycle without a dwell). The
    drive's current steps by itself (healthy Cranfield run 1 at -40 kgf: about 0.1 A in
    every phase, the dwell included, between two cycles, while a stroke less the dwell
    stays within 0.01 A), so the stroke features read the current against it."""
    return _dwell_median(cycle, "current_a", "standstill_current")


def standstill_error(cycle: Cycle) -> float:
    """The median position error of the cycle's dwells (0 without a dwell): the position
    sensor's zero as the cycle sees it."""
    return _dwell_median(cycle, "position_error_mm", "standstill_error")


@dataclass
class PhaseStats:
    """One phase of one load: per aligned sample, the mean and pooled spread."""
    name: str
    direction: int
    setpoint_mm: np.ndarray
    position_mm: np.ndarray
    mean: dict[str, np.ndarray]
    std: dict[str, np.ndarray]
    n: int

    def __len__(self) -> int:
        return len(self.setpoint_mm)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "direction": self.direction, "n": self.n,
                "setpoint_mm": _r(self.setpoint_mm), "position_mm": _r(self.position_mm),
                "mean": {k: _r(v) for k, v in self.mean.items()},
                "std": {k: _r(v) for k, v in self.std.items()}}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> PhaseStats:
        arr = np.asarray
        return cls(d["name"], int(d["direction"]), arr(d["setpoint_mm"], float),
                   arr(d["position_mm"], float),
                   {k: arr(v, float) for k, v in d["mean"].items()},
                   {k: arr(v, float) for k, v in d["std"].items()}, int(d["n"]))


@dataclass
class LoadBaseline:
    """The baseline of one load."""
    load: float
    runs: list[int]
    cycles: list[str]
    phases: dict[str, PhaseStats]
    indexes: dict[str, dict[str, tuple[float, float]]]     # phase -> index -> (mean, sd)
    # the same indexes of the referenced signals (`phase_indexes(referenced=True)`):
    # phase -> index -> (mean, predictive sd of a cycle of a new run, `spread`)
    ref_indexes: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)
    _memo: dict[str, Any] = field(default_factory=dict, init=False, repr=False,
                                  compare=False)

    @property
    def n(self) -> int:
        return len(self.cycles)

    def memo(self, name: str, compute: Any) -> Any:
        """`compute()` once per baseline (what every cycle scored against it reads)."""
        if name not in self._memo:
            self._memo[name] = compute()
        return self._memo[name]

    @property
    def provisional(self) -> bool:
        """Fewer than `spread.MIN_RUNS` runs: too few to estimate the spread between runs."""
        return len(set(self.runs)) < MIN_RUNS


@dataclass
class Baseline:
    """Healthy baselines per load, with where they came from."""
    loads: dict[float, LoadBaseline]
    sources: list[str]
    path: str = ""                         # the file it was read from / written to
    lead_mm: float | None = None           # the screw's lead (position-periodic feature)
    thresholds: dict[str, Any] = field(default_factory=dict)   # set by population
    load_unit: str = ""                    # the unit of the loads (e.g. kgf), "" unknown
    # what `bench rig baseline --update` needs (`update`): the kept cycles, the anchor
    # (the first runs' thresholds), the history of updates
    store: dict[str, Any] = field(default_factory=dict)

    def for_load(self, load: float) -> LoadBaseline:
        for k, v in self.loads.items():
            if math.isclose(k, load, abs_tol=1e-6):
                return v
        raise BenchError(f"the baseline has no load {load:g} (it has "
                         f"{', '.join(f'{k:g}' for k in sorted(self.loads))})")

    def describe(self, load: float | None = None) -> str:
        """Which baseline: file, tables, runs, loads and cycles (named in every verdict)."""
        where = self.path or "(in memory)"
        src = ", ".join(self.sources)
        if load is None:
            parts = [f"load {self.load_text(k)}: runs {_runs(v.runs)}, {v.n} cycles"
                     for k, v in sorted(self.loads.items())]
            return f"baseline {where} from {src}; " + "; ".join(parts)
        lb = self.for_load(load)
        return (f"baseline {where} from {src}, load {self.load_text(load)}, runs "
                f"{_runs(lb.runs)}, {lb.n} healthy cycles")

    def load_text(self, load: float) -> str:
        return f"{load:g} {self.load_unit}".strip()

    def short(self, load: float) -> str:
        """'runs 1,2, load 40 kgf, 10 cycles': the baseline of one load in a few words."""
        lb = self.for_load(load)
        return f"runs {_runs(lb.runs)}, load {self.load_text(load)}, {lb.n} cycles"

    def to_json(self) -> dict[str, Any]:
        return {"format": FORMAT, "sources": self.sources, "thresholds": self.thresholds,
                "lead_mm": self.lead_mm, "load_unit": self.load_unit, "store": self.store,
                "loads": [{"load": lb.load, "runs": lb.runs, "cycles": lb.cycles,
                           "indexes": lb.indexes, "ref_indexes": lb.ref_indexes,
                           "phases": [p.to_json() for p in lb.phases.values()]}
                          for lb in self.loads.values()]}

    def save(self, path: str | Path) -> Path:
        """The baseline as JSON at `path`; BenchError, nothing written, when a threshold is
        not one `load` would read back (`threshold_problem`)."""
        path = Path(path)
        why = threshold_problem(self.thresholds, self.store)
        if why:
            raise BenchError(f"{path}: not written: {why}")
        self.path = str(path)
        path.write_text(json.dumps(self.to_json()))
        return path

    @classmethod
    def load(cls, path: str | Path) -> Baseline:
        path = Path(path)
        try:
            d = json.loads(path.read_text())
        except FileNotFoundError:
            raise BenchError(f"no such baseline: {path}") from None
        except IsADirectoryError:
            raise BenchError(f"{path}: a directory, not a baseline JSON (give the file "
                             "`bench rig baseline --out` wrote)") from None
        except OSError as exc:
            raise BenchError(f"{path}: cannot read the baseline ({exc.strerror or exc})"
                             ) from None
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise BenchError(f"{path}: not a baseline JSON ({exc})") from None
        except RecursionError:
            raise BenchError(f"{path}: not a baseline JSON (nested too deep to read)"
                             ) from None
        return cls.from_json(d, str(path))

    @classmethod
    def from_json(cls, d: Any, path: str = "") -> Baseline:
        """A baseline from its JSON (`to_json`); BenchError naming `path` when it is not
        one."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise BenchError(f"{path}: not a baseline written by `bench rig baseline`")
        loads = {}
        try:
            for e in d["loads"]:
                ph = {p["name"]: PhaseStats.from_json(p) for p in e["phases"]}
                idx = {k: {i: (float(m), float(s)) for i, (m, s) in v.items()}
                       for k, v in e["indexes"].items()}
                ref = {k: {i: (float(m), float(s)) for i, (m, s) in v.items()}
                       for k, v in (e.get("ref_indexes") or {}).items()}
                loads[float(e["load"])] = LoadBaseline(float(e["load"]), list(e["runs"]),
                                                       list(e["cycles"]), ph, idx, ref)
        except (KeyError, TypeError, ValueError) as exc:
            raise BenchError(f"{path}: damaged baseline ({type(exc).__name__}: {exc})"
                             ) from None
        lead = d.get("lead_mm")
        store = d.get("store") or {}
        thr = d.get("thresholds")
        why = threshold_problem({} if thr is None else thr, store)
        if why:
            raise BenchError(f"{path}: damaged baseline: {why}")
        return cls(loads, list(d.get("sources") or []), str(path),
                   None if lead is None else float(lead), dict(d.get("thresholds") or {}),
                   str(d.get("load_unit") or ""), store if isinstance(store, dict) else {})


def threshold_problem(thresholds: Any, store: Any = None) -> str:
    """What is wrong with a baseline's thresholds ("" when nothing): per load (its key,
    e.g. "40") a table of feature thresholds, each a finite number > 0; likewise the
    first runs' thresholds `--update` keeps (`store["anchor"]`). A feature without a
    threshold is absent from its load's table (`population.thresholds`: periodic without
    the lead) and a load without thresholds absent from the file; a score is judged by
    its ratio to the threshold (`features.assess`), so a NaN, an infinite, a zero or a
    negative one would judge every cycle healthy without a word. A threshold of 0 is
    one the healthy scores gave no bound above 0 (`population.threshold_of`), which
    `features.assess` leaves out; a load needs at least one above 0."""
    anchor = store.get("anchor") if isinstance(store, dict) else None
    for what, table in (("", thresholds), ("the first runs' (--update anchor) ", anchor)):
        if table is None and what:
            continue
        if not isinstance(table, dict):
            return f"its {what}thresholds are not a table per load"
        for load, cal in table.items():
            thr = cal.get("thresholds") if isinstance(cal, dict) else None
            if not isinstance(thr, dict) or not thr:
                return f"load {load}: no {what}feature thresholds"
            for feature, value in thr.items():
                if not (isinstance(value, (int, float)) and not isinstance(value, bool)
                        and math.isfinite(value) and value >= 0):
                    return (f"load {load}, feature {feature}: {what}threshold {value!r} "
                            "is not a finite number >= 0")
            if not any(v > 0 for v in thr.values()):
                return f"load {load}: no {what}threshold above 0 (no cycle could be flagged)"
    return ""


def _r(a: np.ndarray) -> list[float]:
    return [round(float(x), 6) for x in a]


def _runs(runs: list[int]) -> str:
    return ",".join(str(r) for r in sorted(set(runs)))


def phase_indexes(cycle: Cycle, referenced: bool = False) -> dict[str, dict[str, float]]:
    """`cycle_indexes`, computed once per cycle (they need no baseline)."""
    return cycle.memo(f"phase_indexes.{referenced}",  # type: ignore[no-any-return]
                      lambda: cycle_indexes(cycle, referenced))


def cycle_indexes(cycle: Cycle, referenced: bool = False) -> dict[str, dict[str, float]]:
    """Per phase of a cycle: mean, RMS and peak current, mean and peak position error, and
    for a stroke the mean current of its acceleration, constant-speed and deceleration
    parts (NaN for an empty part). `referenced`: of the current less the cycle's
    standstill current: a drive's or a current sensor's zero that moves between runs (a
    Hall sensor's offset with temperature; healthy Cranfield run 1 at -40 kgf: 0.1 A in
    every phase between two cycles) moves no referenced index, while friction and a load
    act in motion and move them. (The position error is not referenced: a play held on
    one flank by a one-sided load moves it in every phase, the dwell too.)"""
    out: dict[str, dict[str, float]] = {}
    i, e = cycle.current_a, cycle.position_error_mm
    if referenced:
        i = i - standstill_current(cycle)
    i, e = np.asarray(i, np.float64), np.asarray(e, np.float64)
    for seg in cycle.segments():
        s = slice(seg.start, seg.stop)
        if not len(seg):        # `phases` cuts none; numpy's error if one were
            np.max(i[s])
        # np.mean, np.sqrt(np.mean(x ** 2)) and np.max(np.abs(x)), bit for bit (compiled)
        d = {"current_mean": _mean(i[s]), "current_rms": math.sqrt(_mean(i[s] * i[s])),
             "current_peak": float(K.absmax(i[s])), "position_error_mean": _mean(e[s]),
             "position_error_peak": float(K.absmax(e[s]))}
        if seg.direction:
            for part, sl in cycle.ramps(seg).items():
                d[f"current_{part}"] = _mean(i[sl]) if sl.stop > sl.start else float("nan")
        out[seg.name] = d
    return out


def _mean(x: np.ndarray) -> float:
    """`np.mean` of a non-empty 1-D float64 array, bit for bit (`kernels.psum`)."""
    return float(K.psum(x)) / len(x)


def aligned(cycles: list[Cycle]) -> dict[str, tuple[int, list[np.ndarray]]]:
    """Per phase name: (direction, the cycles' sample index arrays), cut to the shortest
    cycle's phase. Every cycle must have the same phase sequence."""
    seqs = [c.segments() for c in cycles]
    names = [s.name for s in seqs[0]]
    for c, s in zip(cycles, seqs, strict=True):
        if [x.name for x in s] != names:
            raise BenchError(f"{c.label}: its set-point phases ({', '.join(x.name for x in s)}) "
                             f"differ from the other cycles' ({', '.join(names)})")
    out = {}
    for j, name in enumerate(names):
        length = min(len(s[j]) for s in seqs)
        out[name] = (seqs[0][j].direction, [np.arange(s[j].start, s[j].start + length)
                                             for s in seqs])
    return out


def pooled_std(x: np.ndarray) -> np.ndarray:
    """Per-sample spread (ddof 1) of a cycles x samples array, its variance averaged over
    `POOL` neighbouring samples."""
    var = np.var(x, axis=0, ddof=1) if x.shape[0] > 1 else np.zeros(x.shape[1])
    k = min(POOL, x.shape[1])
    pad = k // 2
    padded = np.pad(var, (pad, k - 1 - pad), mode="edge")
    smooth = np.convolve(padded, np.ones(k) / k, mode="valid")
    floor = 1e-6 + 1e-3 * float(np.sqrt(np.mean(var))) if len(var) else 1e-6
    return np.maximum(np.sqrt(smooth), floor)


def build_load(cycles: list[Cycle]) -> LoadBaseline:
    """The baseline of one load from its healthy cycles."""
    if len(cycles) < MIN_CYCLES:
        raise BenchError(f"load {cycles[0].load:g}: a baseline needs at least {MIN_CYCLES} "
                         f"healthy cycles, got {len(cycles)}")
    ph = {}
    al = aligned(cycles)
    _check_repeats(cycles, al)
    for name, (direction, idx) in al.items():
        mean, std = {}, {}
        for sig in SIGNALS:
            x = np.array([signal(c, sig)[k] for c, k in zip(cycles, idx, strict=True)])
            mean[sig] = x.mean(axis=0)
            std[sig] = pooled_std(x)
        sp = np.mean([c.setpoint_mm[k] for c, k in zip(cycles, idx, strict=True)], axis=0)
        pos = np.mean([c.position_mm[k] for c, k in zip(cycles, idx, strict=True)], axis=0)
        ph[name] = PhaseStats(name, direction, sp, pos, mean, std, len(cycles))
    indexes = _per_index([phase_indexes(c) for c in cycles], ph,
                         lambda vals: (float(vals.mean()), float(vals.std(ddof=1))))
    return LoadBaseline(cycles[0].load, sorted({c.run for c in cycles}),
                        [c.label for c in cycles], ph, indexes, ref_indexes(cycles, ph))


def ref_indexes(cycles: list[Cycle], names: Any) -> dict[str, dict[str, tuple[float, float]]]:
    """Per phase and referenced index (`phase_indexes(referenced=True)`): the mean and the
    predictive spread of one cycle of a healthy run not among `cycles`' runs
    (`spread.spread`: within and between runs; with fewer than `spread.MIN_RUNS` runs the
    spread of independent cycles, provisional)."""
    runs = [c.run for c in cycles]

    def stat(vals: np.ndarray) -> tuple[float, float]:
        sp = spread(vals, runs)
        return (sp.mean, math.sqrt(sp.predictive))
    return _per_index([phase_indexes(c, referenced=True) for c in cycles], names, stat)


def _per_index(per: list[dict[str, dict[str, float]]], names: Any,
               stat: Callable[[np.ndarray], tuple[float, float]]
               ) -> dict[str, dict[str, tuple[float, float]]]:
    """Per phase in `names` and index: `stat` of the index over the cycles `per` (one
    `phase_indexes` each); an index not finite in every cycle is left out."""
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for name in names:
        out[name] = {}
        for key in per[0][name]:
            vals = np.array([p[name][key] for p in per], float)
            if np.isfinite(vals).all():
                out[name][key] = stat(vals)
    return out


REPEAT_STEPS = 2.0
"""Aligned set-points may differ by this many set-point steps between cycles (a sampling
instant's jitter); more, and the cycles do not repeat one set-point profile."""


def _check_repeats(cycles: list[Cycle], al: dict[str, tuple[int, list[np.ndarray]]]) -> None:
    """BenchError when the cycles' set-points differ at an aligned sample by more than
    `REPEAT_STEPS` set-point steps: aligned sample k must be the same set-point position
    in every cycle (the baseline compares them sample by sample)."""
    moving = [float(np.max(np.abs(np.diff(c.setpoint_mm)))) for c in cycles if len(c) > 1]
    tol = REPEAT_STEPS * max(moving, default=0.0) + 1e-9
    for name, (_, idx) in al.items():
        sp = np.array([c.setpoint_mm[k] for c, k in zip(cycles, idx, strict=True)])
        if not sp.size:
            continue
        spread = np.ptp(sp, axis=0)
        k = int(np.argmax(spread))
        if spread[k] > tol:
            raise BenchError(f"the cycles do not repeat one set-point profile (phase {name}, "
                             f"aligned sample {k}: set-points {spread[k]:.3g} mm apart, more "
                             f"than {REPEAT_STEPS:g} set-point steps): a baseline needs "
                             "repeated set-point cycles")


def build(cycles: list[Cycle], sources: list[str] | None = None) -> Baseline:
    """Baselines per load from healthy cycles (any number of runs and loads)."""
    if not cycles:
        raise BenchError("no healthy cycles to build a baseline from")
    loads: dict[float, list[Cycle]] = {}
    for c in cycles:
        if not math.isfinite(c.load):
            raise BenchError(f"{c.label}: the cycle's load is unknown (no load column or "
                             "load key); a baseline is per load")
        loads.setdefault(c.load, []).append(c)
    srcs = sources if sources is not None else sorted({c.source for c in cycles})
    return Baseline({k: build_load(v) for k, v in sorted(loads.items())}, srcs)


SHORT_SAMPLES = 2
"""A cycle's phase may be this many samples shorter than the baseline's (a sampling
instant's jitter) and still be judged; shorter, or missing, and the cycle is incomplete."""


def incomplete(lb: LoadBaseline, cycle: Cycle) -> str:
    """Why `cycle` cannot be judged against the baseline ("" when it can): a phase the
    baseline has is missing or cut short (a log that starts or stops inside a cycle). A
    partial cycle judged as a whole would read its missing part as a fault. (On the
    Cranfield development set every one of its 1260 cycles has the baseline's phase
    lengths exactly.)"""
    have = {s.name: len(s) for s in cycle.segments()}
    missing = [name for name in lb.phases if name not in have]
    if missing:
        return (f"incomplete cycle: no {', '.join(missing)} phase ({len(cycle)} samples; "
                f"the baseline's cycle has {', '.join(lb.phases)})")
    short = [f"{name} {have[name]} of {len(ps)} samples" for name, ps in lb.phases.items()
             if have[name] < len(ps) - SHORT_SAMPLES]
    if short:
        return f"incomplete cycle: {', '.join(short)}"
    return ""


def residuals(lb: LoadBaseline, cycle: Cycle, sig: str = "current_a"
              ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per phase of `cycle` that the baseline has: (standardised residual of `sig` per
    aligned sample, the cycle's measured position there in mm). A phase shorter than the
    baseline's is compared over its own length."""
    out = {}
    x = signal(cycle, sig)
    infl = math.sqrt(1.0 + 1.0 / lb.n)
    for seg in cycle.segments():
        ps = lb.phases.get(seg.name)
        if ps is None:
            continue
        m = min(len(seg), len(ps))
        k = slice(seg.start, seg.start + m)
        scale = lb.memo(f"residual_scale.{seg.name}.{sig}.{m}",
                        lambda ps=ps, m=m: ps.std[sig][:m] * infl)
        z = (x[k] - ps.mean[sig][:m]) / scale
        out[seg.name] = (z, cycle.position_mm[k].copy())
    return out
