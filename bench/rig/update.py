"""A healthy baseline that grows run by run (`bench rig baseline --update`), without
absorbing wear.

A baseline keeps the healthy cycles it was built from (`pack`, compressed in the file)
and its first calibration (`anchor`: the runs and thresholds it was first built with).
An operator adds each new healthy run (`update`); per load the run is judged first:

- against the current baseline and its thresholds: more of its cycles flagged than a
  healthy run would give (`too_many`: the binomial tail of the thresholds' false-alarm
  rate below alpha; with 5 cycles and alpha 0.05, two or more) is a **step change**, and
  the run is not added;
- against the anchor (the first runs and their thresholds): as many flagged is a **slow
  change since the first baseline** (wear that crept in run by run, each step inside the
  current spread), and the run is not added either;
- otherwise it is **drift**: the run is added, the baseline and its thresholds are
  rebuilt from every kept cycle (the between-run spread is then estimated from one run
  more; a provisional baseline stops being provisional at 3 runs).

So what is absorbed is a run that both the current baseline and the first one take for
healthy; what is flagged is a run either of them does not. A slow growth is found at the
latest when it has moved as far from the first runs as a fault the first baseline
detects. `--force` adds a refused run anyway (a repair, a new reference), and says so.
"""

from __future__ import annotations

import base64
import math
import zlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig import baseline as B
from bench.rig import population as P
from bench.rig.cycles import Cycle
from bench.rig.features import cycle_features, judge

ARRAYS = ("t_s", "setpoint_mm", "position_mm", "current_a")


def _enc(x: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(np.asarray(x, "<f4").tobytes(), 6)).decode()


def _dec(s: str) -> np.ndarray:
    return np.frombuffer(zlib.decompress(base64.b64decode(s)), "<f4").astype(float)


def pack(cycles: Sequence[Cycle]) -> list[dict[str, Any]]:
    """The cycles as JSON (float32, zlib, base64)."""
    return [{"load": c.load, "run": c.run, "group": c.group, "source": c.source,
             "load_unit": c.load_unit, **{k: _enc(getattr(c, k)) for k in ARRAYS}}
            for c in cycles]


def unpack(data: Sequence[dict[str, Any]]) -> list[Cycle]:
    try:
        return [Cycle(_dec(d["t_s"]), _dec(d["setpoint_mm"]), _dec(d["position_mm"]),
                      _dec(d["current_a"]), float(d["load"]), int(d["run"]),
                      int(d["group"]), str(d["source"]), load_unit=str(d.get("load_unit", "")))
                for d in data]
    except (KeyError, TypeError, ValueError, zlib.error) as exc:
        raise BenchError(f"the baseline's kept cycles are damaged ({type(exc).__name__})"
                         ) from None


def calibrate_all(base: B.Baseline, cycles: Sequence[Cycle], alpha: float) -> list[str]:
    """`base`'s thresholds per load from `cycles` (leave-one-run-out, the spreads pooled
    over the loads); notes for a load with one run (no thresholds)."""
    notes = []
    base.thresholds = {}
    usable = []
    for load in sorted(base.loads):
        if len({c.run for c in cycles if c.load == load}) < 2:
            notes.append(f"load {load:g}: one run only, no thresholds (they need a run held "
                         "out)")
            continue
        usable.append(load)
    if usable:
        cals = P.calibrate_loads([c for c in cycles if c.load in usable], alpha, base.lead_mm)
        base.thresholds = {f"{k:g}": v.to_json() for k, v in cals.items()}
    return notes


def build(cycles: Sequence[Cycle], sources: list[str], lead_mm: float | None,
          load_unit: str, alpha: float) -> tuple[B.Baseline, list[str]]:
    """A baseline that keeps its cycles and its anchor (the first runs' thresholds)."""
    base = B.build(list(cycles), sources)
    base.lead_mm = lead_mm
    base.load_unit = load_unit
    notes = calibrate_all(base, cycles, alpha)
    base.store = {"cycles": pack(cycles), "alpha": alpha,
                  "anchor": {k: {"runs": v["runs"], "thresholds": v["thresholds"]}
                             for k, v in base.thresholds.items()},
                  "history": [{"action": "built", "runs": _runs_by_load(cycles)}]}
    return base, notes


def _runs_by_load(cycles: Sequence[Cycle]) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for c in cycles:
        out.setdefault(f"{c.load:g}", [])
        if c.run not in out[f"{c.load:g}"]:
            out[f"{c.load:g}"].append(c.run)
    return {k: sorted(v) for k, v in out.items()}


def too_many(flagged: int, n: int, alpha: float) -> bool:
    """More flagged cycles than a healthy run gives: P(X >= flagged) < alpha for X
    binomial(n, alpha) (each healthy cycle flagged with probability alpha at most)."""
    from scipy.stats import binom
    return flagged > 0 and float(binom.sf(flagged - 1, n, alpha)) < alpha


def _flagged(lb: B.LoadBaseline, thr: dict[str, float], cycles: Sequence[Cycle],
             lead_mm: float | None) -> tuple[int, int, list[str]]:
    n = k = 0
    effects: list[str] = []
    for c in cycles:
        f = cycle_features(lb, c, lead_mm)
        if f.incomplete:
            continue
        v = judge(f, thr)
        n += 1
        k += int(v.flagged)
        if v.flagged:
            effects.append(v.effect)
    return k, n, effects


def decide(base: B.Baseline, kept: Sequence[Cycle], run: Sequence[Cycle], alpha: float
           ) -> tuple[str, str]:
    """("drift" | "step" | "slow", the reason) for one new run of one load (module
    doc)."""
    load = run[0].load
    key = f"{load:g}"
    cal = base.thresholds.get(key)
    if cal is None:
        return "drift", "no thresholds at this load yet: added"
    k, n, eff = _flagged(base.for_load(load), cal["thresholds"], run, base.lead_mm)
    if too_many(k, n, alpha):
        return "step", (f"{k} of {n} cycles flagged against the current baseline (runs "
                        f"{_list(cal['runs'])}: {', '.join(sorted(set(eff)))})")
    anchor = base.store.get("anchor", {}).get(key)
    if anchor:
        first = [c for c in kept if c.load == load and c.run in anchor["runs"]]
        ka, na, ea = _flagged(B.build_load(first), anchor["thresholds"], run, base.lead_mm)
        if too_many(ka, na, alpha):
            return "slow", (f"{ka} of {na} cycles flagged against the first baseline (runs "
                            f"{_list(anchor['runs'])}: {', '.join(sorted(set(ea)))}), "
                            f"{k} against the current one")
    return "drift", f"{k} of {n} cycles flagged against the current baseline"


def _list(runs: Sequence[int]) -> str:
    return ",".join(str(r) for r in sorted(runs))


def update(base: B.Baseline, new: Sequence[Cycle], force: bool = False,
           sources: Sequence[str] = ()) -> tuple[B.Baseline, list[dict[str, Any]]]:
    """`base` with every new run that is drift (or every run, `force`) added, and each
    run's decision; BenchError for a baseline without kept cycles or a run it has."""
    if "cycles" not in base.store:
        raise BenchError(f"{base.path}: the baseline keeps no cycles (written before "
                         "`--update` existed): build it again from its tables")
    alpha = float(base.store.get("alpha", P.ALPHA))
    kept = unpack(base.store["cycles"])
    have = {(c.load, c.run): c.source for c in kept}
    runs: dict[tuple[float, int], list[Cycle]] = {}
    for c in new:
        if not math.isfinite(c.load):
            raise BenchError(f"{c.label}: the cycle's load is unknown")
        if not any(math.isclose(c.load, k, abs_tol=1e-6) for k in base.loads):
            raise BenchError(f"{c.label}: the baseline has no load {c.load:g}")
        if (c.load, c.run) in have:
            raise BenchError(f"run {c.run} of load {c.load:g} is already in the baseline "
                             f"(from {have[(c.load, c.run)]}): give a new run")
        runs.setdefault((c.load, c.run), []).append(c)
    decisions = []
    added: list[Cycle] = []
    for (load, run), cs in sorted(runs.items()):
        kind, why = decide(base, kept, cs, alpha)
        take = kind == "drift" or force
        decisions.append({"load": load, "run": run, "source": cs[0].source, "kind": kind,
                          "added": take, "forced": take and kind != "drift", "why": why})
        if take:
            added += cs
    if not added:
        return base, decisions
    return rebuilt(base, kept + added, decisions, sources), decisions


def rebuilt(base: B.Baseline, cycles: list[Cycle], decisions: list[dict[str, Any]],
            sources: Sequence[str] = ()) -> B.Baseline:
    """A new baseline from `cycles`, with `base`'s anchor, lead, unit and history (and
    this update's decisions) kept."""
    alpha = float(base.store.get("alpha", P.ALPHA))
    out = B.build(cycles, list(dict.fromkeys([*base.sources, *sources])))
    out.lead_mm, out.load_unit = base.lead_mm, base.load_unit
    calibrate_all(out, cycles, alpha)
    out.store = {"cycles": pack(cycles), "alpha": alpha,
                 "anchor": base.store.get("anchor", {}),
                 "history": [*base.store.get("history", []),
                             {"action": "update", "decisions": decisions}]}
    return out


def text(decisions: Sequence[dict[str, Any]]) -> list[str]:
    """One line per new run: added as drift, or refused as a step or a slow change."""
    words = {"drift": "drift, added", "step": "a step change, not added",
             "slow": "a slow change since the first baseline, not added"}
    out = []
    for d in decisions:
        what = words[d["kind"]]
        if d["forced"]:
            what = what.replace("not added", "added anyway (--force)")
        out.append(f"load {d['load']:g} run {d['run']} ({d['source']}): {what}: {d['why']}")
    return out
