"""A rig's classifier on disk, and `bench rig train` / `bench rig classify`.

The model file is a skops file (scikit-learn's secure format: a zip of JSON and NumPy
arrays, no pickle). It is read only when every type it holds is one the bench trusts
(`TRUSTED`: none beyond the scikit-learn estimator and plain data): a file holding any
other type is refused with one line, not loaded. It carries the rig it was trained on
(`rig_of`: the set-point phases and their lengths, the stroke, the loads and their unit,
the screw's lead, the actuator description's name), and `classify` refuses tables of
another rig.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig import baseline as B
from bench.rig import classify as K
from bench.rig.cycles import Cycle, condition_name

FORMAT = "bench-rig-model/1"
TRUSTED: list[str] = []          # types beyond skops' defaults the bench loads (none)
PHASE_TOLERANCE = 0.05           # a phase may be this share longer or shorter
STROKE_TOLERANCE_MM = 2.0


def rig_of(cycles: Sequence[Cycle], lead_mm: float | None, actuator: str) -> dict[str, Any]:
    """What identifies the rig of `cycles`: phase names and median lengths, the set-point's
    range (mm), the loads, their unit, the lead and the actuator's name."""
    segs = [c.segments() for c in cycles]
    names = [s.name for s in segs[0]]
    lengths = {n: int(np.median([len(s[i]) for s in segs if len(s) > i]))
               for i, n in enumerate(names)}
    sp = np.concatenate([c.setpoint_mm for c in cycles])
    return {"phases": lengths, "stroke_mm": [float(np.min(sp)), float(np.max(sp))],
            "loads": sorted({float(c.load) for c in cycles}),
            "load_unit": next((c.load_unit for c in cycles if c.load_unit), ""),
            "lead_mm": lead_mm, "actuator": actuator}


def check_rig(model_rig: dict[str, Any], cycles: Sequence[Cycle], where: str,
              actuator: str = "") -> None:
    """BenchError (one line) when `cycles` are not of the model's rig."""
    mine = rig_of(cycles, model_rig.get("lead_mm"), actuator)
    want = model_rig.get("actuator") or ""
    why = []
    if actuator and want and actuator != want:
        why.append(f"actuator {actuator}, the model's {want}")
    ph, have = model_rig["phases"], mine["phases"]
    if list(ph) != list(have) or any(
            abs(have[k] - v) > max(2, PHASE_TOLERANCE * v) for k, v in ph.items()):
        why.append("phases " + _phases(have) + ", the model's " + _phases(ph))
    lo, hi = model_rig["stroke_mm"]
    if (abs(mine["stroke_mm"][0] - lo) > STROKE_TOLERANCE_MM
            or abs(mine["stroke_mm"][1] - hi) > STROKE_TOLERANCE_MM):
        why.append(f"set-point {mine['stroke_mm'][0]:.1f}-{mine['stroke_mm'][1]:.1f} mm, "
                   f"the model's {lo:.1f}-{hi:.1f} mm")
    if why:
        raise BenchError(f"{where}: a model of another rig ({'; '.join(why)})")


def _phases(d: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in d.items()) + " samples"


def save(model: K.Model, path: str | Path) -> Path:
    """The model as a skops file."""
    import sklearn
    import skops.io as sio
    bases = B.Baseline(dict(model.bases), ["training tables"])
    payload = {
        "format": FORMAT, "rig": json.dumps(model.rig), "classes": list(model.classes),
        "healthy": model.healthy, "lead_mm": json.dumps(model.lead_mm),
        "columns": list(model.columns.names),
        "norm": {f"{k!r}": [mu, sd] for k, (mu, sd) in model.columns.loads.items()},
        "estimator": model.estimator,
        "novelty": {k: {"location": v["location"], "precision": v["precision"],
                        "bound": float(v["bound"])} for k, v in model.novelty.items()},
        "bases": json.dumps(bases.to_json()), "trained_on": list(model.trained_on),
        "validation": json.dumps(model.validation, default=_json_default),
        "sklearn": sklearn.__version__}
    path = Path(path)
    path.write_bytes(sio.dumps(payload))
    return path


def _json_default(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON: {type(x).__name__}")


def load(path: str | Path) -> K.Model:
    """A model written by `save`; BenchError (one line) for a missing file, a directory, a
    file that is not a skops file, one that holds a type the bench does not trust, or one that is not
    a bench rig model."""
    import skops.io as sio
    path = Path(path)
    if path.is_dir():
        raise BenchError(f"{path}: a directory, not a model (give the file `bench rig "
                         "train -o` wrote)")
    if not path.is_file():
        raise BenchError(f"no such model: {path}")
    data = path.read_bytes()
    try:
        untrusted = sio.get_untrusted_types(data=data)
    except Exception as exc:  # noqa: BLE001 - zipfile, json and skops raise many types
        raise BenchError(f"{path}: not a bench rig model (not a skops file `bench rig "
                         f"train -o` writes: {exc})") from None
    bad = sorted(set(untrusted) - set(TRUSTED))
    if bad:
        raise BenchError(f"{path}: refused: the file holds types the bench does not load "
                         f"({', '.join(bad[:3])}{' ...' if len(bad) > 3 else ''})")
    try:
        d = sio.loads(data, trusted=TRUSTED)
    except Exception as exc:  # noqa: BLE001
        raise BenchError(f"{path}: not a bench rig model (its content does not load: {exc})"
                         ) from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise BenchError(f"{path}: not a model written by `bench rig train`")
    return _model(d, path)


def _model(d: dict[str, Any], path: Path) -> K.Model:
    try:
        cols = K.Columns(list(d["columns"]))
        cols.loads = {float(k): (np.asarray(v[0], float), np.asarray(v[1], float))
                      for k, v in d["norm"].items()}
        bases = B.Baseline.from_json(json.loads(d["bases"]), str(path))
        m = K.Model(list(d["classes"]), cols, d["estimator"],
                    {k: dict(v) for k, v in d["novelty"].items()}, dict(bases.loads),
                    str(d["healthy"]), json.loads(d["lead_mm"]), json.loads(d["rig"]),
                    list(d["trained_on"]), json.loads(d["validation"]))
    except (KeyError, TypeError, ValueError, BenchError) as exc:
        raise BenchError(f"{path}: damaged model ({type(exc).__name__}: {exc})") from None
    if not hasattr(m.estimator, "predict_proba"):
        raise BenchError(f"{path}: damaged model (its estimator cannot classify)")
    return m


def inputs_guard(outputs: Sequence[tuple[str, str]], inputs: Sequence[str]) -> None:
    """BenchError when an output would be written over an input."""
    ins = {Path(p).resolve() for p in inputs}
    for flag, out in outputs:
        if out and out != "-" and Path(out).resolve() in ins:
            raise BenchError(f"{flag} {out}: that is an input; nothing is written over an "
                             "input")


def _bar(total: int, desc: str, unit: str) -> Any:
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit=unit, disable=not sys.stderr.isatty())


def run_train(args: Any, read: Any) -> int:
    """`bench rig train TABLE... -o MODEL`: validate leaving runs out, then train on every
    run and write the model with its validation."""
    from bench.cli.outputs import check_output_file
    check_output_file(args.out, "-o")
    if args.json:
        check_output_file(args.json, "--json", stdout_ok=True)
    inputs_guard([("-o", args.out), ("--json", args.json or "")], args.tables)
    data = K.labelled(args.tables, read)
    K.check_classes(data, args.healthy)
    val: dict[str, Any] = {"not_validated": "--no-validate"}
    if not getattr(args, "no_validate", False):
        folds = K.folds_of(data, args.folds, args.seed)
        with _bar(len(folds), "leave-runs-out folds", "fold") as bar:
            val = K.validate(data, args.healthy, args.lead_mm, args.folds, args.seed, bar)
    with _bar(len(data.cycles), "training", "cycle") as bar:
        model = K.fit(data.cycles, data.labels, data.groups, args.healthy, args.lead_mm, bar)
    model.rig = rig_of(data.cycles, args.lead_mm, getattr(args, "actuator", None) or "")
    model.validation = {k: v for k, v in val.items() if k != "predictions"}
    model.validation["tables"] = sorted({condition_name(t) for t in args.tables})
    save(model, args.out)
    if "bench" in model.validation:
        print(validation_text(model.validation))
    else:
        print("not validated (--no-validate)")
    print(f"written: {args.out} (classes {', '.join(model.classes)}; trained on "
          f"{len(model.trained_on)} runs of {len(data.cycles)} cycles)")
    if args.json:
        _write_json(args.json, model.validation)
    return 0


def _write_json(where: str, obj: Any) -> None:
    text = json.dumps(obj, indent=1, default=_json_default)
    if where == "-":
        sys.stdout.write(text + "\n")
    else:
        Path(where).write_text(text)


def _pct(x: float) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.1f} %"


def validation_text(v: dict[str, Any]) -> str:
    """The leave-runs-out validation as text: the confusion matrix (counts) and each
    class's recall with its interval, the bench's beside the plain reference's."""
    lines = [f"leave-runs-out validation: {v['folds']} folds of whole runs (table, load, "
             f"run), {v['runs']} runs; no run on both sides"]
    for key, name in (("bench", "bench classifier"), ("plain_forest",
                                                      "plain random forest on cycle summaries")):
        s = v[key]
        lines.append(f"{name}: {s['right']} / {s['cycles']} cycles right "
                     f"({_pct(s['rate'])}; 95 % {_pct(s['rate_95'][0])}-{_pct(s['rate_95'][1])})")
        lines.append("  true \\ classified: " + " | ".join(s["columns"]))
        for cls, row in zip(s["classes"], s["confusion"], strict=True):
            r = s["recall"][cls]
            lines.append(f"  {cls}: " + " | ".join(str(x) for x in row)
                         + f"   recall {_pct(r['rate'])} ({_pct(r['rate_95'][0])}-"
                           f"{_pct(r['rate_95'][1])}; {r['runs']} runs)")
    return "\n".join(lines)


def run_classify(args: Any, read: Any) -> int:
    """`bench rig classify MODEL TABLE... --json OUT`: every cycle's class."""
    from bench.cli.outputs import check_output_file
    if args.json:
        check_output_file(args.json, "--json", stdout_ok=True)
    inputs_guard([("--json", args.json or "")], [args.model, *args.tables])
    model = load(args.model)
    out: dict[str, Any] = {"model": str(args.model), "classes": model.classes,
                           "tables": {}}
    for t in args.tables:
        cycles = read(t)
        check_rig(model.rig, cycles, f"{args.model} and {t}",
                  getattr(args, "actuator", None) or "")
        for c in cycles:
            K.match(model.columns.loads, c.load)
        with _bar(len(cycles), condition_name(t), "cycle") as bar:
            res = K.predict(model, cycles, bar)
        out["tables"][condition_name(t)] = table_result(model, t, cycles, res)
    for name, r in out["tables"].items():
        cls = ", ".join(f"{k} {v}" for k, v in sorted(r["classes"].items(),
                                                      key=lambda kv: -kv[1]))
        seen = f"; {r['seen_in_training']} of its cycles' runs were trained on" \
            if r["seen_in_training"] else ""
        print(f"{name}: {r['cycles']} cycles: {cls}{seen}")
    if args.json:
        _write_json(args.json, out)
    return 0


def table_result(model: K.Model, table: str, cycles: Sequence[Cycle],
                 res: list[dict[str, Any]]) -> dict[str, Any]:
    """One table's classes: counts per class (`unknown` for a cycle like no class), the
    label its name gives and the share that agrees, the cycles whose run the model was
    trained on, and every cycle's class."""
    counts: dict[str, int] = {}
    for r in res:
        counts[r["class"]] = counts.get(r["class"], 0) + 1
    name = condition_name(table)
    label = K.table_label(table)
    trained = set(model.trained_on)
    seen = sum(f"{name}|{c.load:g}|{c.run}" in trained for c in cycles)
    return {"cycles": len(cycles), "classes": counts, "label": label,
            "agrees": (counts.get(label, 0) / len(cycles)) if label in model.classes
            else None, "seen_in_training": seen,
            "unknown_text": K.UNKNOWN_TEXT if counts.get(K.UNKNOWN) else None,
            "per_cycle": res}
