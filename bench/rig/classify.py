"""Supervised fault classes of a rig with seeded faults (`bench rig train` / `classify`).

Where labelled runs exist (every rig with seeded faults has them), a classifier learns the
classes from them. A table's label is its file name less anything after the first `_` and
any trailing digits (`table_label`: `backlash1_runs1-5.csv.xz` -> backlash,
`normal_runs5-6` -> normal, `spalling3` -> spalling); the healthy class (`normal` by
default) must be among them.

Each cycle becomes one vector (`cycle_vector`), read without the labels:

- the bench's own phase indexes of the referenced signals (`baseline.phase_indexes(
  referenced=True)`: the current less the standstill current, the position error less its
  dwell median, so that a drive's or a sensor's zero that moves between runs does not
  move them);
- what the physics signatures read (`summary`): each stroke's level, its current and
  position error while it takes up the reversal, its position-error plateau, the
  amplitude (not the phase: a screw re-assembled at another angle moves the phase) of the
  current ripple at the screw's lead, half and twice it, and the dwell's transient;
- the bench's cycle features against the healthy baseline of the training runs
  (`features.cycle_features`: localised, level, reversal, take-up, periodic, dwell and
  index scores and the signed levels; a training healthy cycle is scored against the
  baseline of the other healthy runs, so that it is as far from its baseline as a new
  healthy run is).

Per load, every column is standardised by the training healthy cycles' mean and spread
(a load changes every current), and a multinomial logistic regression (scikit-learn,
balanced class weights: a class of few runs counts as much as one of many) learns the
classes. A cycle like no class gets "unknown (no class within its spread)": per class
the squared Mahalanobis distance to its training cycles (Ledoit-Wolf covariance), and
the class's upper 99 % prediction bound of a cycle of a new run (`spread`: the distances
of each of its runs to the other runs' fit); outside every class's bound, unknown.

Validation leaves whole runs out (`validate`): a run, i.e. a (table, load, run), is
never on both sides; the confusion matrix has counts, and each class's recall its exact
95 % interval (cycles of a run are not independent: the interval is narrower than the
truth; the run counts are given beside it).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig import baseline as B
from bench.rig.cycles import Cycle, condition_name
from bench.rig.features import FEATURES, NAMING_ONLY, cycle_features

UNKNOWN = "unknown"
UNKNOWN_TEXT = "unknown (no class within its spread)"
NOVELTY_ALPHA = 0.01
NOVELTY_FOLDS = 5                     # parts of a class's runs for its novelty bound
TAKEUP = (0, 3, 6, 10, 16, 25)        # sample windows after a stroke starts
SETTLE = 25                           # samples after a stroke starts: the plateau begins


def table_label(path: str) -> str:
    """A table's class label: its file name without the table suffixes, less anything
    after the first `_` and any trailing digits (`backlash1_runs1-5.csv.xz` -> backlash);
    "" when nothing is left."""
    name = condition_name(path).split("_", 1)[0]
    return re.sub(r"\d+$", "", name)


def _amplitude(x: np.ndarray, y: np.ndarray, period: float) -> float:
    """The amplitude of y's component at `period` of x (least squares with a line)."""
    if len(x) < 6:
        return float("nan")
    a = np.column_stack((np.cos(2 * np.pi * x / period), np.sin(2 * np.pi * x / period),
                         np.ones(len(x)), x - x.mean()))
    co = np.linalg.lstsq(a, y, rcond=None)[0]
    return float(math.hypot(co[0], co[1]))


def summary(c: Cycle, lead_mm: float | None) -> dict[str, float]:
    """The physics signatures' raw readings of one cycle (module doc)."""
    f: dict[str, float] = {}
    cur, e, pos = c.current_a, c.position_error_mm, c.position_mm
    ss, e0 = B.standstill_current(c), B.standstill_error(c)
    f["standstill_a"] = ss
    for s in c.segments():
        a, b, d = s.start, s.stop, s.direction
        if not d:
            x, y = cur[a:b] - ss, e[a:b] - e0
            f[f"{s.name}.current_std"] = float(np.std(x))
            for lo, hi in ((0, 5), (5, 15), (15, 30)):
                if hi <= b - a:
                    f[f"{s.name}.e{lo}"] = float(np.mean(y[lo:hi]))
                    f[f"{s.name}.i{lo}"] = float(np.mean(x[lo:hi]))
            continue
        if b - a <= SETTLE + 5:
            continue
        x = cur[a:b] - ss
        y = d * (e[a:b] - e0)                # + is lag along the motion
        f[f"{s.name}.level"] = float(np.mean(x[SETTLE:]))
        f[f"{s.name}.level_end"] = float(np.mean(x[-30:]))
        f[f"{s.name}.ripple_std"] = float(np.std(np.diff(x[SETTLE:])))
        f[f"{s.name}.lag"] = float(np.mean(y[SETTLE:]))
        f[f"{s.name}.lag_peak"] = float(np.max(y[:SETTLE]))
        f[f"{s.name}.lag_slope"] = float(np.polyfit(np.arange(b - a - SETTLE), y[SETTLE:], 1)[0])
        for lo, hi in zip(TAKEUP[:-1], TAKEUP[1:], strict=True):
            f[f"{s.name}.i{lo}"] = float(np.mean(x[lo:hi]))
            f[f"{s.name}.e{lo}"] = float(np.mean(y[lo:hi]))
        if lead_mm:
            for k, per in (("lead", lead_mm), ("half", lead_mm / 2), ("twice", 2 * lead_mm)):
                f[f"{s.name}.ripple_{k}"] = _amplitude(pos[a + SETTLE:b], x[SETTLE:], per)
    return f


def cycle_vector(c: Cycle, lb: B.LoadBaseline | None, lead_mm: float | None
                 ) -> dict[str, float]:
    """Every column of one cycle (module doc); the bench's cycle features only with a
    healthy baseline `lb`."""
    out = dict(own_vector(c, lead_mm))
    if lb is not None:
        f = cycle_features(lb, c, lead_mm)
        # the naming-only features (the hysteresis) name a flagged cycle for the physics
        # route; the classifier keeps the columns it was built on
        out.update({f"feat.{k}": f.scores[k] for k in FEATURES if k not in NAMING_ONLY})
        out.update({"feat.level_out": f.level_out, "feat.level_in": f.level_in,
                    "feat.reversal_signed": f.reversal_signed,
                    **{f"feat.takeup_{k}": v for k, v in f.takeup_z.items()}})
    return out


def own_vector(c: Cycle, lead_mm: float | None) -> dict[str, float]:
    """The columns of one cycle that need no baseline (its phase indexes and `summary`),
    computed once per cycle."""
    def own() -> dict[str, float]:
        d = {f"idx.{ph}.{k}": v for ph, x in B.phase_indexes(c, referenced=True).items()
             for k, v in x.items()}
        d.update({f"sig.{k}": v for k, v in summary(c, lead_mm).items()})
        return d
    return c.memo(f"classify.own.{lead_mm}", own)  # type: ignore[no-any-return]


def own_vectors(job: tuple[list[Cycle], float | None]) -> list[dict[str, float]]:
    """`own_vector` of each of the job's cycles (a worker job)."""
    cycles, lead_mm = job
    return [own_vector(c, lead_mm) for c in cycles]


OWN_PARTS = 8           # worker jobs the cycles' own columns are computed in, once


@dataclass
class Labelled:
    """Cycles of labelled tables: each with its label and its run's group."""
    cycles: list[Cycle]
    labels: list[str]
    tables: list[str]

    @property
    def groups(self) -> list[str]:
        """A run: (table, load, run); never split between training and validation."""
        return [f"{t}|{c.load:g}|{c.run}" for t, c in zip(self.tables, self.cycles,
                                                          strict=True)]


def labelled(tables: Sequence[str], read: Any) -> Labelled:
    """The cycles of `tables` (read with `read(path)`) with their labels; BenchError for a
    table whose name gives no label."""
    cycles: list[Cycle] = []
    labels: list[str] = []
    names: list[str] = []
    for t in tables:
        lab = table_label(t)
        if not lab:
            raise BenchError(f"{t}: no label in the table's name (the label is the file "
                             "name less anything after the first '_' and trailing digits, "
                             "e.g. backlash1_runs1-5.csv.xz -> backlash)")
        mine = read(t)
        cycles += mine
        labels += [lab] * len(mine)
        names += [condition_name(t)] * len(mine)
    return Labelled(cycles, labels, names)


def check_classes(data: Labelled, healthy: str) -> None:
    """BenchError unless there are two classes or more, the healthy one among them, and
    every class has at least two runs (a run is left out whole in validation)."""
    classes = sorted(set(data.labels))
    if healthy not in classes:
        raise BenchError(f"no table of the healthy class {healthy!r} among the labels "
                         f"({', '.join(classes)}): the model standardises each load by its "
                         "healthy runs (--healthy names another label)")
    if len(classes) < 2:
        raise BenchError(f"only one class ({classes[0]}): a classifier needs two or more")
    runs: dict[str, set[str]] = {}
    for lab, g in zip(data.labels, data.groups, strict=True):
        runs.setdefault(lab, set()).add(g)
    one = sorted(k for k, v in runs.items() if len(v) < 2)
    if one:
        raise BenchError(f"class {', '.join(one)} has one run only: leave-runs-out "
                         "validation needs at least two runs of every class")


@dataclass
class Columns:
    """The column names and the per-load healthy mean and spread that standardise them."""
    names: list[str]
    loads: dict[float, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    def fit(self, x: np.ndarray, loads: np.ndarray, healthy: np.ndarray) -> None:
        for load in np.unique(loads):
            m = (loads == load) & healthy
            if m.sum() < 2:
                raise BenchError(f"load {load:g}: fewer than two healthy training cycles; "
                                 "the columns cannot be standardised at that load")
            xm = x[m]
            ok = np.isfinite(xm)
            n = ok.sum(axis=0)
            mu = np.where(n > 0, np.where(ok, xm, 0.0).sum(axis=0) / np.maximum(n, 1), 0.0)
            var = np.where(ok, (xm - mu) ** 2, 0.0).sum(axis=0) / np.maximum(n - 1, 1)
            sd = np.sqrt(var)
            self.loads[float(load)] = (mu, np.where((n > 1) & (sd > 0), sd, 1.0))

    def transform(self, x: np.ndarray, loads: np.ndarray) -> np.ndarray:
        out = np.empty_like(x)
        for load in np.unique(loads):
            key = match(self.loads, float(load))
            mu, sd = self.loads[key]
            out[loads == load] = (x[loads == load] - mu) / sd
        return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)


def match(loads: dict[float, Any], load: float) -> float:
    """The model's load within 5 % of `load` (BenchError when none)."""
    for k in loads:
        if math.isclose(k, load, rel_tol=0.05, abs_tol=1e-6):
            return k
    raise BenchError(f"load {load:g}: the model has no healthy runs at that load (it has "
                     f"{', '.join(f'{k:g}' for k in sorted(loads))})")


def healthy_baselines(cycles: Sequence[Cycle], labels: Sequence[str], healthy: str
                      ) -> dict[float, B.LoadBaseline]:
    """The healthy baseline of each load the healthy training cycles have (3 or more)."""
    out: dict[float, B.LoadBaseline] = {}
    for load in sorted({c.load for c, lab in zip(cycles, labels, strict=True)
                        if lab == healthy}):
        mine = [c for c, lab in zip(cycles, labels, strict=True)
                if lab == healthy and c.load == load]
        if len(mine) >= B.MIN_CYCLES:
            out[float(load)] = B.build_load(mine)
    return out


def vectors(cycles: Sequence[Cycle], labels: Sequence[str] | None,
            bases: dict[float, B.LoadBaseline], lead_mm: float | None, healthy: str,
            names: list[str] | None = None, progress: Any = None) -> tuple[np.ndarray, list[str]]:
    """The cycles' vectors (rows) and column names. With `labels` (training), a healthy
    cycle is scored against the baseline of the other healthy runs of its load
    (leave-one-run-out), as a healthy run the model has not seen would be."""
    rows: list[dict[str, float]] = []
    loro: dict[tuple[float, int], B.LoadBaseline | None] = {}
    for i, c in enumerate(cycles):
        lb = bases.get(match(bases, c.load)) if bases else None
        if labels is not None and labels[i] == healthy and lb is not None:
            key = (c.load, c.run)
            if key not in loro:
                rest = [x for x, lab in zip(cycles, labels, strict=True) if lab == healthy
                        and x.load == c.load and x.run != c.run]
                loro[key] = B.build_load(rest) if len(rest) >= B.MIN_CYCLES else None
            lb = loro[key]
        rows.append(cycle_vector(c, lb, lead_mm))
        if progress is not None:
            progress.update(1)
    cols = names if names is not None else sorted({k for r in rows for k in r})
    x = np.array([[r.get(k, np.nan) for k in cols] for r in rows], float)
    return x, cols


@dataclass
class Model:
    """A trained classifier with what it needs to judge a new cycle."""
    classes: list[str]
    columns: Columns
    estimator: Any
    novelty: dict[str, dict[str, Any]]
    bases: dict[float, B.LoadBaseline]
    healthy: str
    lead_mm: float | None
    rig: dict[str, Any] = field(default_factory=dict)
    trained_on: list[str] = field(default_factory=list)     # the runs (groups) it learnt
    validation: dict[str, Any] = field(default_factory=dict)


def _estimator() -> Any:
    from sklearn.linear_model import LogisticRegression
    return LogisticRegression(C=0.3, max_iter=5000, class_weight="balanced")


def fit(cycles: Sequence[Cycle], labels: Sequence[str], groups: Sequence[str],
        healthy: str, lead_mm: float | None, progress: Any = None) -> Model:
    """A model from labelled cycles (their runs `groups` kept for the novelty bound)."""
    bases = healthy_baselines(cycles, labels, healthy)
    x, names = vectors(cycles, labels, bases, lead_mm, healthy, progress=progress)
    loads = np.array([c.load for c in cycles], float)
    y = np.asarray(labels)
    cols = Columns(names)
    cols.fit(x, loads, y == healthy)
    xs = cols.transform(x, loads)
    est = _estimator().fit(xs, y)
    return Model(sorted(set(labels)), cols, est, novelty_fit(xs, y, np.asarray(groups)),
                 bases, healthy, lead_mm, trained_on=sorted(set(groups)))


def _mahalanobis(x: np.ndarray, loc: np.ndarray, precision: np.ndarray) -> np.ndarray:
    d = x - loc
    return np.einsum("ij,jk,ik->i", d, precision, d)


def _cov(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from sklearn.covariance import LedoitWolf
    lw = LedoitWolf().fit(x)
    return lw.location_, lw.precision_


def novelty_fit(xs: np.ndarray, y: np.ndarray, groups: np.ndarray) -> dict[str, dict[str, Any]]:
    """Per class: its training cycles' location and precision (Ledoit-Wolf), and the
    upper (1 - `NOVELTY_ALPHA`) prediction bound of the log squared distance of a cycle
    of a new run, from each run's distances to the fit of the class's other runs
    (`spread.spread`)."""
    from bench.rig.spread import spread
    out: dict[str, dict[str, Any]] = {}
    for lab in sorted(set(y)):
        m = y == lab
        loc, prec = _cov(xs[m])
        vals: list[float] = []
        runs: list[str] = []
        mine = np.unique(groups[m])
        for part in np.array_split(mine, min(NOVELTY_FOLDS, len(mine))):
            out_ = m & np.isin(groups, part)
            rest = m & ~out_
            if rest.sum() < 3:
                continue
            lo, pr = _cov(xs[rest])
            d = _mahalanobis(xs[out_], lo, pr)
            vals += list(np.log(np.maximum(d, 1e-12)))
            runs += list(groups[out_])
        sp = spread(vals, runs)
        bound = float(np.exp(sp.upper(NOVELTY_ALPHA))) if len(vals) >= 3 else float("inf")
        out[lab] = {"location": loc, "precision": prec, "bound": bound}
    return out


def predict(model: Model, cycles: Sequence[Cycle], progress: Any = None
            ) -> list[dict[str, Any]]:
    """Each cycle's class (or `UNKNOWN`), its probability and its distances to the
    classes over their bounds."""
    x, _ = vectors(cycles, None, model.bases, model.lead_mm, model.healthy,
                   names=model.columns.names, progress=progress)
    loads = np.array([c.load for c in cycles], float)
    xs = model.columns.transform(x, loads)
    proba = model.estimator.predict_proba(xs)
    classes = list(model.estimator.classes_)
    ratio = {lab: _mahalanobis(xs, nv["location"], nv["precision"]) / nv["bound"]
             for lab, nv in model.novelty.items()}
    out = []
    for i, c in enumerate(cycles):
        k = int(np.argmax(proba[i]))
        near = {lab: float(r[i]) for lab, r in ratio.items()}
        inside = any(v <= 1.0 for v in near.values())
        out.append({"cycle": c.label, "class": classes[k] if inside else UNKNOWN,
                    "nearest": classes[k], "probability": float(proba[i, k]),
                    "distance_over_bound": near})
    return out


def plain_summary(c: Cycle) -> list[float]:
    """The plain reference's columns: the load and the mean, spread, least, largest and
    RMS of the current and of the position error over the whole cycle."""
    out = [float(c.load)]
    for x in (c.current_a, c.position_error_mm):
        out += [float(np.mean(x)), float(np.std(x)), float(np.min(x)), float(np.max(x)),
                float(np.sqrt(np.mean(x ** 2)))]
    return out


def _plain_forest() -> Any:
    from sklearn.ensemble import RandomForestClassifier
    return RandomForestClassifier(n_estimators=200, random_state=0, n_jobs=1)


def folds_of(data: Labelled, n_folds: int, seed: int = 0) -> list[np.ndarray]:
    """The validation folds: whole runs (`Labelled.groups`), stratified by class
    (scikit-learn's StratifiedGroupKFold); at most as many folds as the class with the
    fewest runs has runs."""
    from sklearn.model_selection import StratifiedGroupKFold
    groups = np.asarray(data.groups)
    runs: dict[str, set[str]] = {}
    for lab, g in zip(data.labels, groups, strict=True):
        runs.setdefault(lab, set()).add(g)
    k = max(2, min(n_folds, min(len(v) for v in runs.values())))
    cv = StratifiedGroupKFold(n_splits=k, shuffle=True, random_state=seed)
    y = np.asarray(data.labels)
    return [test for _, test in cv.split(np.zeros(len(y)), y, groups)]


def fold(job: tuple[Any, ...]) -> tuple[list[str], list[str]]:
    """One validation fold (a worker job): the bench's classifier and the plain forest
    trained on the fold's training runs, their classes for its test cycles."""
    import warnings
    cycles, labels, groups, test, healthy, lead_mm, xp, owns = job
    for c, v in zip(cycles, owns or [], strict=False):    # computed once for every fold
        c.memo(f"classify.own.{lead_mm}", lambda v=v: v)
    y = np.asarray(labels)
    train = np.setdiff1d(np.arange(len(y)), test)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # a fold's convergence notes
        m = fit([cycles[i] for i in train], list(y[train]), [groups[i] for i in train],
                healthy, lead_mm)
        pred = [r["class"] for r in predict(m, [cycles[i] for i in test])]
        plain = _plain_forest().fit(xp[train], y[train]).predict(xp[test])
    return pred, [str(p) for p in plain]


def validate(data: Labelled, healthy: str, lead_mm: float | None, n_folds: int = 5,
             seed: int = 0, progress: Any = None, run: Any = None) -> dict[str, Any]:
    """Leave-runs-out validation of the bench's classifier and, on the same folds, of the
    plain reference (a random forest on `plain_summary`): each fold's runs are
    classified by models trained on the other runs only. `run(fn, jobs)` maps the folds
    (e.g. over workers, each fold's cycles a copy: the cycles' own columns are then
    computed once, in `OWN_PARTS` jobs, and sent with every fold; default: here, one
    after the other)."""
    y = np.asarray(data.labels)
    xp = np.array([plain_summary(c) for c in data.cycles])
    groups = np.asarray(data.groups)
    folds = folds_of(data, n_folds, seed)
    owns = None
    if run is not None:
        parts = [p for p in np.array_split(np.arange(len(y)), OWN_PARTS) if len(p)]
        got = run(own_vectors, [([data.cycles[i] for i in p], lead_mm) for p in parts])
        owns = [v for part in got for v in part]
    jobs = [(data.cycles, data.labels, data.groups, test, healthy, lead_mm, xp, owns)
            for test in folds]
    if run is None:
        done = []
        for j in jobs:
            done.append(fold(j))
            if progress is not None:
                progress.update(1)
    else:
        done = run(fold, jobs)
    pred = np.empty(len(y), dtype=object)
    plain = np.empty(len(y), dtype=object)
    for test, (p, q) in zip(folds, done, strict=True):
        pred[test] = p
        plain[test] = q
    loads = np.array([c.load for c in data.cycles], float)
    return {"folds": len(folds), "seed": seed, "runs": len(set(groups)),
            "bench": scores(y, pred, groups, loads),
            "plain_forest": scores(y, plain, groups, loads),
            "predictions": [str(p) for p in pred]}


def scores(y: np.ndarray, pred: np.ndarray, groups: np.ndarray, loads: np.ndarray
           ) -> dict[str, Any]:
    """The confusion matrix (counts; the columns add `UNKNOWN`), every class's recall with
    its exact 95 % interval and its number of runs, and the share of cycles right, overall
    and per load."""
    from bench.rig.population import clopper_pearson
    classes = sorted(set(y))
    cols = classes + ([UNKNOWN] if UNKNOWN in set(pred) else [])
    conf = [[int(np.sum((y == a) & (pred == b))) for b in cols] for a in classes]
    recall: dict[str, dict[str, Any]] = {}
    for a in classes:
        n = int(np.sum(y == a))
        k = int(np.sum((y == a) & (pred == a)))
        recall[a] = {"right": k, "cycles": n, "rate": k / n if n else float("nan"),
                     "rate_95": clopper_pearson(k, n), "runs": len(set(groups[y == a]))}
    right = int(np.sum(pred == y))
    per_load = {}
    for load in np.unique(loads):
        m = loads == load
        k = int(np.sum(pred[m] == y[m]))
        per_load[f"{load:g}"] = {"right": k, "cycles": int(m.sum()),
                                 "rate": k / int(m.sum()),
                                 "rate_95": clopper_pearson(k, int(m.sum()))}
    return {"classes": classes, "columns": cols, "confusion": conf, "recall": recall,
            "right": right, "cycles": len(y), "rate": right / len(y) if len(y) else
            float("nan"), "rate_95": clopper_pearson(right, len(y)), "per_load": per_load,
            "least_recall": min((float(r["rate"]) for r in recall.values()),
                                default=float("nan"))}
