"""The study report's tables against the goals: per load, on runs no threshold, rule or
classifier used, the healthy false-alarm rate, the detection rate per fault table, the
fault named (physics, and the supervised classes), each with its interval, and beside
them what a plain per-sample z-score and a plain random forest on cycle summaries get on
the same split (`bench rig study`; the blocks `report.document` adds)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from bench.reports import Block, Heading, Paragraph, Table
from bench.rig import naming
from bench.rig.classify import table_label
from bench.rig.population import clopper_pearson, naming_summary


def pct(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.1f} %"


def ci(iv: list[float] | None) -> str:
    if not iv or not all(math.isfinite(x) for x in iv):
        return "-"
    return f"{100 * iv[0]:.1f}-{100 * iv[1]:.1f} %"


def _rate(k: int, n: int, iv: list[float] | None) -> str:
    return f"{k} / {n} ({pct(k / n if n else float('nan'))}; {ci(iv)})"


def _counts(d: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(d.items(), key=lambda kv: -kv[1])) or "-"


def _table(header: list[str]) -> Table:
    return Table(header, [], [False] * len(header))


def false_alarm_blocks(sm: dict[str, Any]) -> list[Block]:
    rows = [(load, row) for load, row in sm["loads"].items() if row.get("cross_validation")]
    if not rows:
        return []
    cv0 = rows[0][1]["cross_validation"]
    table = _table(["load", "bench, cross-validated (95 % interval)",
                    "plain z-score, same splits", "this split's held-out runs",
                    "plain z-score, this split"])
    out: list[Block] = [
        Heading("Healthy runs that did not calibrate", 3), Paragraph(
           f"Per load, the healthy cycles flagged when each choice of {cv0['k']} of the "
           f"healthy runs {','.join(map(str, cv0['runs']))} calibrates ({cv0['splits']} "
           "splits) and the other runs are judged (every rate on runs no threshold used); "
           "the plain z-score's threshold set the plain way from the same calibration runs "
           "(independent cycles, log-normal bound); the held-out runs of this study's own "
           "split:"), table]
    for load, row in rows:
        cv, h = row["cross_validation"], row["holdout"]
        prov = " (provisional: fewer than 3 calibration runs)" if row.get("provisional") else ""
        table.rows.append([
            load, _rate(cv["flagged"], cv["judged"], cv["rate_95"]),
            _rate(cv.get("zscore_flagged", 0), cv["judged"], cv.get("zscore_rate_95")),
            _rate(h["flagged"], h["cycles"], h.get("rate_95")) + prov,
            _rate(h.get("zscore_cal_flagged", 0), h["cycles"], h.get("zscore_cal_rate_95"))])
    return out


def _pooled(row: dict[str, Any], cond: str) -> dict[str, Any] | None:
    r = (row.get("cross_validation") or {}).get("faults", {}).get(cond)
    return (r or {}).get("pooled")


def _pooled_cells(sm: dict[str, Any], loads: list[str], cond: str, need: str,
                  cell: Callable[[dict[str, Any]], str]) -> list[str]:
    """One fault table's cells, a load each: `cell` of its pooled result, "-" where
    that has no `need` (no cycle judged, none flagged)."""
    cells = []
    for load in loads:
        p = _pooled(sm["loads"][load], cond)
        cells.append(cell(p) if p and p[need] else "-")
    return cells


def _family_rates(per_family: dict[str, Any], num: str, den: str) -> str:
    return "; ".join(f"{k} {_rate(v[num], v[den], v['rate_95'])}" for k, v in per_family.items())


def detection_blocks(sm: dict[str, Any], conds: list[str]) -> list[Block]:
    loads = list(sm["loads"])
    table = _table(["table"] + [f"load {k}" for k in loads])
    out: list[Block] = [
        Heading("Fault cycles detected", 3), Paragraph(
           "Per fault table and load, pooled over the same splits (each cycle judged under "
           "every choice of calibration runs; no fault cycle enters a threshold): the bench, "
           "then the plain z-score:"), table]
    def cell(p: dict[str, Any]) -> str:
        return (f"{pct(p['flagged'] / p['judged'])} "
                f"({ci(clopper_pearson(p['flagged'], p['judged']))}); "
                f"z-score {pct(p['zscore_flagged'] / p['judged'])}")

    for cond in conds:
        table.rows.append([cond] + _pooled_cells(sm, loads, cond, "judged", cell))
    g = sm.get("goals", {}).get("detected") or {}
    if g.get("judged"):
        fam = _family_rates(g.get("per_family") or {}, "flagged", "judged")
        out.append(Paragraph(f"All fault cycles: {_rate(g['flagged'], g['judged'], g['rate_95'])} "
                             f"detected; per family: {fam}; the plain z-score "
                             f"{pct(g['zscore_rate'])}."))
    return out


def summary_blocks(sm: dict[str, Any]) -> list[Block]:
    """The goals in one table: each rate, on runs not used, with its interval."""
    g = sm.get("goals") or {}
    rows: list[list[str]] = []
    fa = g.get("false_alarms") or {}
    if fa:
        worst = max(fa.items(), key=lambda kv: kv[1]["rate"])
        cells = "; ".join(f"{k} kgf {pct(v['rate'])} ({ci(v['rate_95'])})" for k, v in fa.items())
        rows.append(["healthy cycles flagged, per load, cross-validated", "<= 5 %", cells,
                     "yes" if worst[1]["rate"] <= 0.05 else "no"])
    d = g.get("detected") or {}
    if d.get("judged"):
        rows.append(["fault cycles detected", ">= 90 %", f"{pct(d['rate'])} ({ci(d['rate_95'])})",
                     "yes" if d["rate"] >= 0.9 else "no"])
    n = g.get("named") or {}
    if n.get("flagged"):
        fam = "; ".join(f"{k} {pct(v['rate'])}" for k, v in n["per_family"].items())
        # pooled, the largest family (the spall stages) would hide the others: the goal
        # holds when it holds for the pool and for every family
        low = [k for k, v in n["per_family"].items()
               if not (math.isfinite(v["rate"]) and v["rate"] >= 0.7)]
        met = ("yes" if n["rate"] >= 0.7 and not low else
               "no" + (f" ({', '.join(low)} below)" if low else ""))
        rows.append(["physics name right on flagged fault cycles, pooled and per family",
                     ">= 70 %", f"{pct(n['rate'])} ({ci(n['rate_95'])}); per family: {fam}", met])
    v = (sm.get("supervised") or {}).get("validation") or {}
    if "bench" in v:
        b = v["bench"]
        rows.append(["supervised, leaving runs out", ">= 90 %; >= 80 % every class",
                     f"{pct(b['rate'])} ({ci(b['rate_95'])}); least class recall "
                     f"{pct(b['least_recall'])}",
                     "yes" if b["rate"] >= 0.9 and b["least_recall"] >= 0.8 else "no"])
    if not rows:
        return []
    return [Table(["goal", "target", "result (95 % interval)", "met"], rows, [False] * 4,
                  role="summary")]


def naming_blocks(sm: dict[str, Any], conds: list[str]) -> list[Block]:
    loads = list(sm["loads"])
    table = _table(["table", "expected"] + [f"load {k}" for k in loads])
    out: list[Block] = [
        Heading("The fault named (physics, no labels)", 3), Paragraph(
           "Per fault table and load, over the flagged cycles pooled over the splits: the "
           "share named the family the table's label names (backlash, friction, spall; "
           "'friction or backlash' counts as not right) and the names given:"), table]
    for cond in conds:
        exp = naming.expected_fault(table_label(cond))

        def cell(p: dict[str, Any], exp: str | None = exp) -> str:
            s = naming_summary(p["faults"], exp)
            right = f"{pct(s['rate'])} ({ci(s['rate_95'])}); " if exp else ""
            return right + _counts(p["faults"])
        table.rows.append([cond, exp or "-"] + _pooled_cells(sm, loads, cond, "flagged", cell))
    g = sm.get("goals", {}).get("named") or {}
    if g.get("flagged"):
        fam = _family_rates(g["per_family"], "right", "flagged")
        out.append(Paragraph(f"All flagged fault cycles: "
                             f"{_rate(g['right'], g['flagged'], g['rate_95'])} named right; "
                             f"per family: {fam}."))
    return out


def supervised_blocks(sm: dict[str, Any]) -> list[Block]:
    sup = sm.get("supervised") or {}
    v = sup.get("validation")
    out: list[Block] = []
    if v and "skipped" in v:
        out.append(Paragraph(f"Supervised classes: not validated ({v['skipped']})."))
    elif v:
        out += [Heading("Supervised classes, leaving whole runs out", 3), Paragraph(
                f"{v['folds']} folds of whole runs (table, load, run; {v['runs']} runs), "
                "stratified by class; no run on both sides. The bench's classifier "
                "(logistic regression on the bench's features and phase indexes, "
                "standardised per load by the healthy runs; 'unknown' outside every "
                "class's spread) and the plain random forest on cycle summaries, on the "
                "same folds:")]
        for key, name in (("bench", "bench"), ("plain_forest", "plain random forest")):
            s = v[key]
            table = Table(["true \\ classified", *s["columns"], "recall (95 %)", "runs"], [])
            for cls, row in zip(s["classes"], s["confusion"], strict=True):
                r = s["recall"][cls]
                table.rows.append([cls, *map(str, row), f"{pct(r['rate'])} ({ci(r['rate_95'])})",
                                   str(r["runs"])])
            out += [Paragraph(f"{name}: {_rate(s['right'], s['cycles'], s['rate_95'])} right; "
                              "per load: " + "; ".join(f"{ld} {pct(r['rate'])}"
                                                       for ld, r in s["per_load"].items())),
                    table]
    m = sup.get("model")
    if m:
        out.append(Paragraph(f"Model {m['path']} (classes {', '.join(m['classes'])}): on the "
                f"{m['cycles']} cycles of runs it was not trained on "
                f"({m['cycles_seen_in_training']} cycles of runs it learnt left out): "
                f"{_rate(m['right'], m['cycles_of_known_classes'], m['rate_95'])} right "
                "(of the cycles of its classes)."))
    return out


def goal_blocks(study: Any) -> list[Block]:
    """Every table of this module for `study`'s summary, as report blocks."""
    sm = study.summary
    conds = list(study.fault_conditions)
    out: list[Block] = [Heading("Against the goals (runs not used)"), *summary_blocks(sm),
                        *false_alarm_blocks(sm)]
    if conds:
        out += detection_blocks(sm, conds) + naming_blocks(sm, conds)
    return out + supervised_blocks(sm)
