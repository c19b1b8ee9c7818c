"""The healthy-baseline fallback, chosen automatically.

When `bench calibrate HEALTHY... --actuator DESC --holdout ...` finds that no model of the
family reaches `FLOOR_FACTOR` x the noise floor on the held-out healthy logs, it also
builds the healthy baseline (`bench.rig.baseline`) from the healthy logs it fitted, with
thresholds set as `bench.rig.population` sets them (leave-one-run-out over the
calibration runs only; the held-out logs enter neither the baseline nor a threshold),
writes it next to the calibration (CAL.baseline.json) and names it in the calibration
(`baseline_for_calibration`). `bench gap LOG --nominal CAL.json` and `bench hums report
LOG --nominal CAL.json` then judge a log against that baseline, and say so in one line
(`choose` -> `Reference.line`).

Where the healthy logs cannot make a baseline (fewer than `baseline.MIN_CYCLES` cycles
of a load, cycles that do not repeat one set-point profile, no load known) or cannot set
its thresholds (one run only), the calibration says why and the verdicts stay against
the model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.core.verdict import Level
from bench.rig import baseline as B
from bench.rig import population as P
from bench.rig.cycles import Cycle, cycle_numbers, cycles_from_trace, load_unit, phases
from bench.rig.features import cycle_features, verdict
from bench.signals.units import convert

FLOOR_FACTOR = 2.0       # as bench.rig.rigcal.FLOOR_FACTOR (the calibration carries its own)
AGAINST = ("auto", "model", "baseline")
LOAD_TOLERANCE = 0.05    # a log's load matches a baseline load within 5 %


def log_cycles(trace: Any, name: str, run: int | None = None,
               skipped: list[str] | None = None) -> list[Cycle]:
    """The motion cycles of one log (`cycles.cycles_from_trace`; those it cannot read
    are listed in `skipped`), BenchError when none."""
    lost: list[str] = []
    cycles = cycles_from_trace(trace, name, run, skipped=lost)
    if skipped is not None:
        skipped += lost
    if not cycles:
        why = f" ({'; '.join(lost[:3])})" if lost else ""
        raise BenchError(f"{name}: no complete motion cycle of 8 samples or more in the "
                         f"log{why}")
    return cycles


def build_from_logs(paths: Sequence[str | Path], lead_mm: float | None,
                    alpha: float = P.ALPHA) -> tuple[B.Baseline, list[str]]:
    """The healthy baseline of `paths` and its thresholds per load (notes: which runs set
    them, or why a load has none). A log without a run key is its own run (its position
    in `paths`, from 1)."""
    from bench.bus.logs import load_trace
    cycles: list[Cycle] = []
    sources: list[str] = []
    lost: list[str] = []
    unit = ""
    for k, p in enumerate(paths, start=1):
        tr = load_trace(p)
        cycles += log_cycles(tr, Path(p).name, run=k, skipped=lost)
        src = Path(str(tr.meta.get("source", p))).name
        if src not in sources:
            sources.append(src)
        unit = unit or load_unit(tr.meta)
    base = B.build(cycles, sources)
    base.lead_mm = lead_mm
    base.load_unit = unit
    notes = [f"not in the baseline: {x}" for x in lost]
    usable = []
    for load in sorted(base.loads):
        runs = sorted({c.run for c in cycles if c.load == load})
        if len(runs) < 2:
            notes.append(f"load {base.load_text(load)}: one healthy run only (run "
                         f"{runs[0]}): no thresholds (they need two or more runs, one held "
                         "out at a time)")
            continue
        usable.append(load)
    cals = P.calibrate_loads([c for c in cycles if c.load in usable], alpha, lead_mm) \
        if usable else {}
    for load, cal in cals.items():
        runs = cal.runs
        base.thresholds[f"{load:g}"] = cal.to_json()
        notes.append(f"load {base.load_text(load)}: thresholds from calibration runs "
                     f"{','.join(map(str, runs))} only (leave-one-run-out, alpha "
                     f"{alpha:g}): " + ", ".join(f"{k} {v:.3g}"
                                                  for k, v in cal.thresholds.items()))
    return base, notes


def baseline_path(cal_output: str | Path) -> Path:
    """CAL.json -> CAL.baseline.json beside it."""
    p = Path(cal_output)
    return p.with_name(p.name[: -len(".json")] + ".baseline.json"
                       if p.name.endswith(".json") else p.name + ".baseline.json")


def baseline_for_calibration(cal: dict[str, Any], healthy: Sequence[str | Path],
                             cal_output: str, lead_mm: float | None) -> list[str]:
    """Build, write and reference the healthy baseline when the calibration does not reach
    the floor (module doc); the notes to print. Sets cal["baseline"] (file name relative
    to the calibration, runs, loads, cycles) or cal["baseline_not_available"]. `lead_mm`,
the screw's lead, enables the position-periodic feature."""
    if cal.get("reaches_noise_floor"):
        return []
    try:
        base, notes = build_from_logs(healthy, lead_mm)
    except BenchError as exc:
        cal["baseline"] = None
        cal["baseline_not_available"] = str(exc)
        return [f"no healthy baseline from these logs ({exc}): the verdicts stay against "
                "the model"]
    if cal_output == "-":
        cal["baseline"] = None
        cal["baseline_not_available"] = "the calibration went to stdout (give -o FILE.json)"
        return ["no healthy baseline written: the calibration went to stdout (give -o "
                "FILE.json to write one beside it)"]
    from bench.core.filenames import check_not_input
    check_not_input(baseline_path(cal_output), "-o")     # beside the calibration
    out = base.save(baseline_path(cal_output))
    cal["baseline"] = {"file": out.name, "sources": base.sources,
                       "loads": {f"{k:g}": {"runs": v.runs, "cycles": v.n,
                                            "thresholds": f"{k:g}" in base.thresholds}
                                 for k, v in base.loads.items()},
                       "load_unit": base.load_unit, "lead_mm": lead_mm,
                       "built_because": "no model of the family reaches "
                                        f"{cal.get('floor_factor', FLOOR_FACTOR):g} x the "
                                        "noise floor on the held-out healthy logs",
                       "notes": notes}
    cal.pop("baseline_not_available", None)
    return [f"healthy baseline written: {out} ({base.describe()}); bench gap and bench "
            "hums report with --nominal this calibration judge logs against it"] + notes


def model_ratio(cal: dict[str, Any]) -> float:
    """The worst RMS / noise floor the calibrated model left on the held-out healthy logs
    (the calibration logs when none was held out)."""
    rows = cal.get("holdout_summary") or {}
    if rows:
        return max(float(r["ratio_max"]) for r in rows.values())
    vals = [float(v["ratio"]) for s in cal.get("fit_scores", []) for v in s.values()]
    return max(vals) if vals else float("nan")


@dataclass
class Reference:
    """What a log's verdict is judged against, and the one line saying so."""
    kind: str                                  # "model", "baseline" or "none"
    why: str                                   # the reason, for the line
    baseline: B.Baseline | None = None
    calibration: dict[str, Any] | None = None
    cal_path: str = ""
    notes: list[str] = field(default_factory=list)

    def line(self, load: float | Sequence[float] | None = None) -> str:
        """One line: what the verdict is judged against (and why); `load`: the baseline
        load(s) a log's cycles were judged at (default: every load of the baseline)."""
        if self.kind == "baseline" and self.baseline is not None:
            base = self.baseline
            want = [load] if isinstance(load, (int, float)) else list(load or [])
            want = [k for k in want if _has_load(base, k)] or sorted(base.loads)
            what = "; ".join(base.short(k) for k in want)
            return f"{self.why}: judged against the healthy baseline {base.path} ({what})"
        if self.kind == "model":
            return f"{self.why}: judged against the calibrated model {self.cal_path}"
        return self.why


def _has_load(base: B.Baseline, load: float) -> bool:
    try:
        base.for_load(load)
    except BenchError:
        return False
    return True


def _ratio_text(cal: dict[str, Any]) -> str:
    held = "held-out" if cal.get("holdout_summary") else "calibration"
    return f"on {held} healthy logs (x{model_ratio(cal):.3g})"


def choose(cal: dict[str, Any] | None, cal_path: str | Path | None,
           baseline: str | Path | None = None, against: str = "auto") -> Reference:
    """The reference of the verdicts (module doc): an explicit --baseline, else the
    calibration's own baseline when its model does not reach the floor, else the model."""
    if against not in AGAINST:
        raise BenchError(f"--against must be one of {', '.join(AGAINST)}")
    if baseline is not None and against != "model":
        return Reference("baseline", "given with --baseline", B.Baseline.load(baseline),
                         cal, str(cal_path or ""))
    if cal is None:
        if against != "auto":
            raise BenchError(f"--against {against} needs " + (
                "--nominal CAL.json" if against == "model" else "--baseline BASE.json or a "
                "calibration that wrote one"))
        return Reference("none", "no reference given (--nominal CAL.json or --baseline "
                         "BASE.json): model-free indexes only, no verdict")
    path = str(cal_path)
    factor = float(cal.get("floor_factor", FLOOR_FACTOR))
    if cal.get("reaches_noise_floor"):
        if against == "baseline":
            raise BenchError(f"{path}: the model reaches the noise floor, so the calibration "
                             "wrote no healthy baseline; give --baseline BASE.json")
        return Reference("model", f"model within {factor:g} x the noise floor "
                         f"{_ratio_text(cal)}", None, cal, path)
    above = f"model above the noise floor {_ratio_text(cal)}"
    if against == "model":
        return Reference("model", f"{above}; --against model", None, cal, path)
    base, why_not = calibration_baseline(cal, path)
    if base is None:
        if against == "baseline":
            raise BenchError(f"{path}: no healthy baseline ({why_not})")
        return Reference("model", f"{above}, and no healthy baseline ({why_not})", None,
                         cal, path)
    return Reference("baseline", above, base, cal, path)


def calibration_baseline(cal: dict[str, Any], cal_path: str
                         ) -> tuple[B.Baseline | None, str]:
    """The baseline a calibration names (read from beside it), or None and why not."""
    ref = cal.get("baseline")
    if not isinstance(ref, dict) or not ref.get("file"):
        return None, str(cal.get("baseline_not_available")
                         or "the calibration names none: re-run bench calibrate")
    where = Path(cal_path).parent / str(ref["file"])
    try:
        return B.Baseline.load(where), ""
    except BenchError as exc:
        return None, f"the calibration's baseline cannot be read: {exc}"


def in_unit(load: float, unit: str, target: str) -> float:
    """`load` in `unit` expressed in `target` (unchanged when either is unknown)."""
    return convert(load, unit, target, "force")


def match_load(base: B.Baseline, load: float) -> tuple[float | None, str]:
    """The baseline load a cycle's load (in the baseline's unit) is judged at (exact, else
    the nearest within `LOAD_TOLERANCE`, else the only one when the load is unknown), and
    a note."""
    loads = sorted(base.loads)
    has = ", ".join(base.load_text(k) for k in loads)
    if math.isfinite(load):
        for k in loads:
            if math.isclose(k, load, abs_tol=1e-6):
                return k, ""
        near = min(loads, key=lambda k: abs(k - load))
        if abs(near - load) <= LOAD_TOLERANCE * max(abs(load), 1e-9):
            return near, (f"the cycle's load {base.load_text(float(f'{load:.4g}'))} judged at "
                          f"the baseline's {base.load_text(near)}")
        return None, (f"load {base.load_text(float(f'{load:.4g}'))} is not in the baseline "
                      f"(it has {has})")
    if len(loads) == 1:
        return loads[0], ("the cycle's load is unknown: judged at the baseline's only load "
                          f"{base.load_text(loads[0])}")
    return None, f"the cycle's load is unknown and the baseline has several ({has})"


def phase_index_table(lb: B.LoadBaseline, cycles: Sequence[Cycle]
                      ) -> list[dict[str, Any]]:
    """Per phase and index: the log's mean over its cycles, the baseline's mean and spread,
    and z = (value - mean) / spread (None where the spread is 0)."""
    per = [B.phase_indexes(c) for c in cycles]
    rows = []
    for ph, idx in lb.indexes.items():
        for key, (m, s) in idx.items():
            vals = [p[ph][key] for p in per if ph in p and key in p[ph]]
            vals = [v for v in vals if math.isfinite(v)]
            if not vals:
                continue
            v = float(np.mean(vals))
            rows.append({"phase": ph, "index": key, "value": v, "baseline_mean": m,
                         "baseline_sd": s, "z": (v - m) / s if s > 0 else None})
    return rows


def cycle_loads(trace: Any, cycles: Sequence[Cycle]) -> list[float]:
    """Each cycle's load in the log's unit (`cycles.load_unit`): the split key (or the
    metadata's `load`) when the log has one, else that cycle's median logged load (N, 3
    significant digits, as `cycles_from_trace` gives the whole log's)."""
    keys = trace.meta.get("split") or {}
    if "load" in keys or "load" in trace.meta or "load_force_n" not in trace:
        return [c.load for c in cycles]
    f = np.asarray(trace["load_force_n"], float)
    group = (np.full(len(f), float(keys["group"])) if "group" in keys
             else cycle_numbers(np.asarray(trace["setpoint_position_m"], float)))
    out = []
    for c in cycles:
        v = f[(group == c.group) & np.isfinite(f)]
        out.append(float(f"{float(np.median(v)):.3g}") if len(v) else c.load)
    return out


def _no_baseline(base: B.Baseline, load: float, unit: str) -> str:
    """'no baseline at load X (= Y in the baseline's unit)' ('' for an unknown load)."""
    if not math.isfinite(load):
        return ""
    conv = in_unit(load, unit, base.load_unit)
    also = (f" (= {base.load_text(float(f'{conv:.4g}'))})"
            if unit != base.load_unit and conv != load else "")
    return f"no baseline at load {f'{load:g} {unit}'.strip()}{also}"


def _unjudged(c: Cycle, load: float, why: str) -> dict[str, Any]:
    return {"cycle": c.label, "level": Level.UNKNOWN.name, "flagged": False, "judged": False,
            "effect": None,
            "verdict": f"not judged: {why}", "reasons": [], "baseline": None,
            "location_mm": None, "load": load, "baseline_load": None}


def assess(base: B.Baseline, trace: Any, name: str) -> dict[str, Any]:
    """A log's cycles against the baseline, each at its own load (`cycle_loads`, matched
    with `match_load`): per cycle the features and verdict and which load of the baseline
    judged it ("not judged: no baseline at load X" where the baseline lacks the cycle's
    load, the other cycles run), the phase indexes against the baseline's per load, and
    the log's result (flagged cycles, effects). Raises BenchError with the reason when no
    cycle can be judged against it."""
    notes: list[str] = []
    cycles = log_cycles(trace, name, skipped=notes)
    unit = load_unit(trace.meta)
    verdicts: list[dict[str, Any]] = []
    feats = []
    at: dict[float, list[Cycle]] = {}
    missed: list[str] = []
    for c, own in zip(cycles, cycle_loads(trace, cycles), strict=True):
        load, note = match_load(base, in_unit(own, unit, base.load_unit))
        if load is None:
            c.load = own              # the cycle's label names its own load
            verdicts.append(_unjudged(c, own, _no_baseline(base, own, unit) or note))
            missed += [note] if note not in missed else []
            continue
        if note and note not in notes:
            notes.append(note)
        c.load = load                 # judged at the baseline's load (the note says so)
        at.setdefault(load, []).append(c)
        f = cycle_features(base.for_load(load), c, base.lead_mm)
        feats.append(f)
        thr = (base.thresholds.get(f"{load:g}") or {}).get("thresholds")
        if not thr:
            verdicts.append(_unjudged(c, own, f"no thresholds for load "
                                      f"{base.load_text(load)} in {base.path} (they need two "
                                      "or more healthy runs): features without a verdict"))
            continue
        if f.incomplete:
            verdicts.append(_unjudged(c, own, f.incomplete))
            continue
        ratios = [f.scores[k] / t for k, t in thr.items()
                  if t > 0 and math.isfinite(f.scores.get(k, math.nan))]
        verdicts.append({**verdict(base, f, thr), "judged": True, "load": own,
                         "baseline_load": load,
                         "features_above": sum(r > 1.0 for r in ratios),
                         "largest_ratio": max(ratios, default=0.0)})
    if not at:
        raise BenchError("; ".join(missed))
    have = {s.name for s in phases(cycles[0].setpoint_mm)}
    if not {"out", "in"} <= have:
        notes.append(f"the log's cycles have phases {', '.join(sorted(have))}: the features "
                     "need an out- and an in-stroke")
    return _result(base, at, cycles, verdicts, feats, notes)


def _result(base: B.Baseline, at: dict[float, list[Cycle]], cycles: Sequence[Cycle],
            verdicts: list[dict[str, Any]], feats: list[Any], notes: list[str]
            ) -> dict[str, Any]:
    judged = [v for v in verdicts if v["judged"]]
    flagged = [v for v in judged if v["flagged"]]
    effects: dict[str, int] = {}
    for v in flagged:
        effects[v["effect"]] = effects.get(v["effect"], 0) + 1
    skipped = [v for v in verdicts if not v["judged"]]
    why = list(dict.fromkeys(v["verdict"][len("not judged: "):] for v in skipped))
    if any(w.startswith("no baseline at load") for w in why):
        why.append("the baseline has " + ", ".join(base.load_text(k)
                                                   for k in sorted(base.loads)))
    if skipped and judged:
        notes.append(f"{len(skipped)} of {len(verdicts)} cycle(s) not judged: "
                     + "; ".join(why))
    elif skipped:
        notes.append("; ".join(why))
    thr = {f"{k:g}": (base.thresholds.get(f"{k:g}") or {}).get("thresholds") for k in at}
    one = next(iter(at)) if len(at) == 1 else None
    return {"against": "baseline",
            "baseline": base.describe(one) if one is not None
            else f"baseline {base.path} from {', '.join(base.sources)}; "
                 + "; ".join(base.short(k) for k in sorted(at)),
            "load": one, "loads": {f"{k:g}": len(v) for k, v in sorted(at.items())},
            "thresholds": thr[f"{one:g}"] if one is not None else None,
            "thresholds_by_load": thr, "cycles": len(cycles), "judged_cycles": len(judged),
            "flagged": len(flagged), "effects": effects, "verdicts": verdicts,
            "worst": worst_cycle(verdicts),
            "features": [f.to_json() for f in feats],
            "phase_indexes": [{"load": k, **r} for k, cs in sorted(at.items())
                              for r in phase_index_table(base.for_load(k), cs)],
            "notes": notes, "judged": bool(judged)}


def worst_cycle(verdicts: Sequence[dict[str, Any]]) -> int | None:
    """The index (in `verdicts`) of the cycle the report's figure shows: the most flagged
    judged one (the most features above their thresholds, then the largest score over
    its threshold), else the first judged one; None when no cycle was judged."""
    judged = [i for i, v in enumerate(verdicts) if v["judged"]]
    if not judged:
        return None
    return max(judged, key=lambda i: (verdicts[i]["features_above"],
                                      verdicts[i]["largest_ratio"], -i))


def loads_judged(res: dict[str, Any]) -> list[float]:
    """The baseline loads an `assess` result's cycles were judged at."""
    return [float(k) for k in res["loads"]]


def text(res: dict[str, Any]) -> str:
    """The baseline diagnosis of a log in a few lines: per cycle its verdict and the load
    of the baseline that judged it."""
    lines = []
    for v in res["verdicts"]:
        if not v["judged"]:
            lines.append(f"  {v['cycle']}: {v['verdict']}")
            continue
        lines.append(f"  {v['cycle']}: {'FLAGGED' if v['flagged'] else 'ok'}: {v['verdict']}"
                     f" [baseline load {v['baseline_load']:g}]")
        lines.append("    " + "; ".join(v["reasons"]))
    lines += [f"  note: {n}" for n in res["notes"]]
    if res["judged"]:
        eff = ", ".join(f"{k} {n}" for k, n in res["effects"].items())
        rest = res["cycles"] - res["judged_cycles"]
        lines.append(f"verdict: {res['flagged']} / {res['judged_cycles']} cycle(s) flagged"
                     + (f" ({eff})" if eff else "")
                     + (f", {rest} not judged" if rest else "")
                     + f" (against the {res['baseline']})")
    else:
        lines.append(f"verdict: not available ({res['notes'][-1]})")
    return "\n".join(lines)
