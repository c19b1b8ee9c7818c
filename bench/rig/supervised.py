"""The supervised part of `bench rig study`: the bench's classifier and the plain random
forest on cycle summaries, validated leaving whole runs out on the study's own labelled
tables (`classify.validate`), per load and per table; and, with `--model`, a trained
model's classes on the cycles of runs it was not trained on."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig import classify as K
from bench.rig.cycles import Cycle
from bench.rig.population import clopper_pearson


def _labelled(todo: Sequence[tuple[str, list[Cycle]]]) -> K.Labelled:
    cycles = [c for _, cs in todo for c in cs]
    return K.Labelled(cycles, [K.table_label(c.source) for c in cycles],
                      [c.source for c in cycles])


def per_table(data: K.Labelled, pred: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Per table and load: cycles, right, the rate with its interval, the classes given."""
    out: dict[str, dict[str, Any]] = {}
    for c, lab, table, p in zip(data.cycles, data.labels, data.tables, pred, strict=True):
        row = out.setdefault(table, {}).setdefault(f"{c.load:g}", {"cycles": 0, "right": 0,
                                                                     "classes": {}})
        row["cycles"] += 1
        row["right"] += int(p == lab)
        row["classes"][p] = row["classes"].get(p, 0) + 1
    for loads in out.values():
        for row in loads.values():
            row["rate"] = row["right"] / row["cycles"]
            row["rate_95"] = clopper_pearson(row["right"], row["cycles"])
    return out


def run(todo: Sequence[tuple[str, list[Cycle]]], healthy: str, lead_mm: float | None,
        model: str | None, workers: int | None, progress: bool, scheduler: str | None,
        validate: bool = True) -> dict[str, Any]:
    """{"validation": leave-runs-out scores and per-table rates (or "skipped": why),
    "model": the given model's classes on runs it did not learn}."""
    import time
    data = _labelled(todo)
    # only the loads the healthy runs have (the study lists the others as not scored)
    loads = {c.load for c, lab in zip(data.cycles, data.labels, strict=True) if lab == healthy}
    keep = [i for i, c in enumerate(data.cycles) if c.load in loads]
    data = K.Labelled([data.cycles[i] for i in keep], [data.labels[i] for i in keep],
                      [data.tables[i] for i in keep])
    out: dict[str, Any] = {}
    if validate:
        t0 = time.perf_counter()
        try:
            K.check_classes(data, healthy)
            from bench.runtime.workers import run_all

            def mapped(fn: Any, jobs: list[Any]) -> list[Any]:
                own = fn is K.own_vectors
                return run_all(fn, jobs, workers=workers, progress=progress,
                               desc="cycle summaries" if own else "classifier folds",
                               unit="part" if own else "fold", scheduler=scheduler)
            v = K.validate(data, healthy, lead_mm, run=mapped)
        except BenchError as exc:
            out["validation"] = {"skipped": str(exc)}
        else:
            v["per_table"] = per_table(data, v.pop("predictions"))
            v["seconds"] = time.perf_counter() - t0
            out["validation"] = v
    if model:
        out["model"] = with_model(model, data)
    return out


def with_model(path: str, data: K.Labelled) -> dict[str, Any]:
    """A model's classes on `data`'s cycles of runs it was not trained on (those it was
    are counted apart, never scored)."""
    from bench.rig.model_io import check_rig, load
    m = load(path)
    check_rig(m.rig, data.cycles, f"{path} and the study's tables")
    seen = set(m.trained_on)
    keep = [i for i, g in enumerate(data.groups) if g not in seen]
    sub = K.Labelled([data.cycles[i] for i in keep], [data.labels[i] for i in keep],
                     [data.tables[i] for i in keep])
    res = K.predict(m, sub.cycles) if keep else []
    pred = [r["class"] for r in res]
    y = np.asarray(sub.labels)
    known = np.isin(y, m.classes)
    right = int(np.sum((np.asarray(pred) == y) & known)) if keep else 0
    return {"path": str(path), "classes": m.classes, "trained_on_runs": len(seen),
            "cycles_seen_in_training": len(data.cycles) - len(keep),
            "cycles": len(keep), "cycles_of_known_classes": int(known.sum()),
            "right": right, "rate": right / int(known.sum()) if known.sum() else float("nan"),
            "rate_95": clopper_pearson(right, int(known.sum())),
            "per_table": per_table(sub, pred)}
