"""`bench rig`: real rigs that no physics model fits. `baseline` builds the
healthy baseline (and its thresholds from held-out healthy runs), `assess` diagnoses
cycles against it, `study` runs a rig's development set end to end, `inject` injects
known faults into held-out healthy cycles (sensitivity per fault kind and size). See
docs/real-data.md."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from bench.cli import options as opt
from bench.signals.units import FORCE

DESCRIPTIONS = {
    "baseline": "A healthy baseline from the given healthy runs: per load, set-point "
        "phase, direction and aligned sample, the mean and pooled spread of "
        "current and position error; and the thresholds of every feature from "
        "leave-one-run-out prediction on those runs. Writes BASE.json, which "
        "`bench rig assess`, `bench gap --baseline` and `bench hums report "
        "--baseline` read.",
    "assess": "Judge every motion cycle of the given tables or traces against a "
        "baseline (`bench rig baseline`), each at its own load: flagged or not, "
        "the effect named (friction- or backlash-like, localised, periodic, "
        "...) and where it lies; per condition the share of cycles flagged. "
        "Incomplete cycles are not judged.",
    "study": "A development set end to end: the baseline and thresholds from the "
        "calibration runs, the false-alarm rate on the held-out healthy runs "
        "(and cross-validated over the choices of calibration runs), the "
        "detection rate and effect named per fault table and load, where the "
        "effect lies, and the cost. Writes report.md, report.html, study.json, "
        "baseline.json and the figures into --out.",
    "inject": "Known faults (friction, backlash, a play under a one-sided load, a "
        "localised bump, a periodic line) injected into the held-out healthy "
        "cycles at sizes in units of the healthy spread, then judged against the "
        "baseline of the calibration runs: the detection rate and the share "
        "named right per kind, size and load.",
    "train": "Learn fault classes from labelled tables: the label is the file name less "
        "trailing digits and anything after the first _ (normal_runs1-4 -> normal). "
        "Per load, standardised cycle features into a balanced logistic regression, "
        "validated leaving whole runs out (a confusion matrix and each class's recall "
        "with its exact 95 % interval); a cycle outside every class's spread is "
        "'unknown'. Writes the model (a skops file with the rig it was trained on).",
    "classify": "Classify every motion cycle of the given tables or traces with a model "
        "of `bench rig train`: its class, or 'unknown' when it lies outside every "
        "class's spread; refused when the tables are of another rig than the model's.",
}
"""What each action does (its --help)."""


LEAD_MM = (0.1, 100.0)
"""The range of a ball-screw lead --lead-mm may give, mm: the range an actuator
description's lead_m is read in (`bench.rig.actuator.MECHANISM`), wide of the screws made
(about 0.5 mm a turn for a miniature one to about 50 mm for a high-lead one). A lead
outside it is a unit or a typing mistake, and the position-periodic feature would look
for a line the screw cannot make."""
ALPHA = (1e-6, 0.5)
"""The range of --alpha, the false-alarm rate the thresholds aim at (the lower end
included): the thresholds are prediction bounds from a few dozen held-out healthy scores,
and below 1e-6 the bound lies so far in the tail that it is the assumed distribution's,
not the data's (near 1e-300 it overflows to infinity); at 0.5 or above every other
healthy cycle would be flagged."""


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    p = opt.add_command(
        subparsers, "rig",
        "baselines, fault signatures and populations of a real rig's runs", """
        For a rig no physics model fits: a baseline from several healthy runs aligned by
        set-point phase (per phase, direction and load), position-locked, position-periodic and
        direction-split features against it, thresholds from held-out healthy runs, detection
        and false-alarm rates per condition. Tables: CSV (plain or .xz/.gz/.bz2) or Parquet with
        set_point, position_error (mm), current (A), load, run, group (one motion cycle), time;
        or `bench import` traces (.npz/.parquet).""")
    sub = p.add_subparsers(dest="rig_command", metavar="ACTION")
    b = sub.add_parser("baseline", help="build a healthy baseline and its thresholds",
                       description=DESCRIPTIONS["baseline"])
    b.add_argument("tables", nargs="+", metavar="HEALTHY", help="healthy tables or traces")
    b.add_argument("--runs", metavar="LIST", help="runs to use (e.g. 1,2; default: all)")
    opt.add_out(b, "baseline file", metavar="BASE.json", required=True, short=True)
    b.add_argument("--update", metavar="BASE.json",
                   help="add the tables' healthy runs to this baseline (each run judged "
                        "first: drift is added, a step or a slow change since the first "
                        "baseline is not); the result goes to --out, the old file stays")
    b.add_argument("--force", action="store_true",
                   help="with --update: add a run judged a change anyway")
    b.add_argument("--load-unit", choices=tuple(FORCE), metavar="UNIT",
                   help=f"unit of a rig table's load column ({', '.join(FORCE)}), so that a log "
                        "whose load is logged in N is matched to it; `bench import` traces "
                        "carry theirs")
    _common(b)
    a = sub.add_parser("assess", help="diagnose cycles against a baseline",
                       description=DESCRIPTIONS["assess"])
    a.add_argument("tables", nargs="+", metavar="LOG", help="tables or traces to assess")
    a.add_argument("--baseline", required=True, metavar="BASE.json")
    a.add_argument("--runs", metavar="LIST", help="only these runs (default: all)")
    opt.add_json(a, "write every verdict here ('-': stdout)")
    a.add_argument("-q", "--quiet", action="store_true", help="only the per-condition rates")
    s = sub.add_parser("study", help="a rig's development set end to end, with a report",
                       description=DESCRIPTIONS["study"])
    s.add_argument("directory", metavar="DIR", help="folder of the rig's tables")
    s.add_argument("--calibrate-runs", required=True, metavar="LIST",
                   help="healthy runs the baseline and thresholds use (e.g. 1,2)")
    s.add_argument("--holdout-runs", required=True, metavar="LIST",
                   help="healthy runs kept out of every threshold (e.g. 3,4)")
    s.add_argument("--healthy", default="normal", metavar="PREFIX",
                   help="name prefix of the healthy table(s); several tables (e.g. runs "
                        "1-4 and 5-10) are one healthy condition (default: normal)")
    s.add_argument("--only", metavar="A,B", help="fault tables to score (default: all)")
    opt.add_out(s, "report folder", required=True, short=True)
    s.add_argument("--model", metavar="MODEL", help="a model of `bench rig train`: its "
                   "classes on the cycles of runs it was not trained on")
    s.add_argument("--no-supervised", action="store_true",
                   help="skip the leave-runs-out validation of the classifiers on the "
                        "folder's labelled tables")
    opt.add_workers(s)
    opt.add_scheduler(s)
    _common(s)
    i = sub.add_parser("inject", help="sensitivity: known faults injected into held-out "
                       "healthy cycles, detection and naming per size",
                       description=DESCRIPTIONS["inject"])
    i.add_argument("tables", nargs="+", metavar="HEALTHY", help="healthy tables or traces")
    i.add_argument("--calibrate-runs", required=True, metavar="LIST",
                   help="healthy runs the baseline and thresholds use (e.g. 1,2)")
    i.add_argument("--holdout-runs", required=True, metavar="LIST",
                   help="healthy runs the faults are injected into (e.g. 3,4)")
    i.add_argument("--sizes", metavar="LIST", help="fault sizes in units of the healthy "
                   "spread, each > 0 and at most 50 (a play of 50 spreads of the position "
                   "error is most of a nut length on the Cranfield rig; default "
                   "0.25,0.5,1,2,4,8)")
    i.add_argument("--kinds", metavar="LIST", help="fault kinds (default: friction,"
                   "backlash,loaded_play,localised,periodic)")
    i.add_argument("--at-mm", type=float, metavar="MM", help="centre of the localised "
                   "bump, measured position (default: the middle of the out-stroke)")
    opt.add_out(i, "report folder", required=True, short=True)
    _common(i)
    t, k = _supervised_parsers(sub)
    for q in (b, a, s, i, t, k):
        q.set_defaults(func=run)
    p.set_defaults(func=run, rig_parser=p)


def _supervised_parsers(sub: argparse._SubParsersAction) -> tuple[Any, Any]:
    """The parsers of `bench rig train` and `bench rig classify`."""
    t = sub.add_parser("train", help="learn fault classes from labelled tables (the label "
                                     "is the file name less trailing digits and anything "
                                     "after the first _), validated leaving runs out",
                          description=DESCRIPTIONS["train"])
    t.add_argument("tables", nargs="+", metavar="TABLE", help="labelled tables or traces")
    opt.add_out(t, "model file (skops)", metavar="MODEL", required=True, short=True)
    t.add_argument("--healthy", default="normal", metavar="LABEL",
                   help="the healthy class's label (default: normal)")
    t.add_argument("--folds", type=int, default=5, help="leave-runs-out folds (default 5)")
    opt.add_seed(t, 0, f"seed of the folds, {opt.SEED_RANGE[0]} to {opt.SEED_RANGE[1]}")
    opt.add_json(t, "write the validation here ('-': stdout)")
    t.add_argument("--no-validate", action="store_true",
                   help="train only, without the leave-runs-out validation (the model then "
                        "says it was not validated)")
    _common(t)
    k = sub.add_parser("classify", help="classify every cycle with a model of `bench rig "
                                        "train`", description=DESCRIPTIONS["classify"])
    k.add_argument("model", metavar="MODEL", help="model file of `bench rig train`")
    k.add_argument("tables", nargs="+", metavar="TABLE", help="tables or traces")
    opt.add_json(k, "write the classes here ('-': stdout)", metavar="OUT")
    k.add_argument("--actuator", metavar="DESC", help="the actuator the tables are of "
                   "(checked against the model's)")
    return t, k


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--lead-mm", type=float, metavar="MM",
                   help=f"the screw's lead in mm, {LEAD_MM[0]:g} to {LEAD_MM[1]:g} (enables "
                        "the position-periodic feature; Cranfield: 5)")
    p.add_argument("--actuator", metavar="DESC",
                   help="actuator description (.json/.toml or a shipped name, e.g. "
                        "cranfield): its lead_m when --lead-mm is not given")
    p.add_argument("--alpha", type=float, default=0.05, metavar="A",
                   help=f"false-alarm rate the thresholds aim at, {ALPHA[0]:g} to below "
                        f"{ALPHA[1]:g} (a smaller one is beyond what a few dozen held-out "
                        "healthy scores can bound; default 0.05)")


MAX_RUNS = 10_000
"""The most runs one range of --runs may name (a rig's test campaign has dozens)."""


def runs_list(text: str | None, flag: str) -> list[int] | None:
    """'1,2' or '1-4' or '1,3-4' -> [1, 2, ...]; None -> None."""
    from bench import BenchError
    if text is None:
        return None
    out: list[int] = []
    try:
        for part in text.split(","):
            a, _, b = part.strip().partition("-")
            if b and int(b) - int(a) > MAX_RUNS:
                raise BenchError(f"{flag}: {part.strip()} is more than {MAX_RUNS} runs")
            out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    except ValueError:
        raise BenchError(f"{flag}: expected run numbers like 1,2 or 1-4, got {text!r}"
                         ) from None
    if not out:
        raise BenchError(f"{flag}: no run given")
    return sorted(set(out))


def _check(args: argparse.Namespace) -> None:
    """BenchError for an option out of its range, before any work (the lead, from
    --lead-mm or the --actuator description, in `LEAD_MM`; --alpha in `ALPHA`; --seed
    in `options.SEED_RANGE`; --workers, --folds)."""
    from bench import BenchError
    given = "--lead-mm"
    if getattr(args, "actuator", None) and getattr(args, "rig_command", "") == "classify":
        from bench.rig.actuator import load
        load(args.actuator)          # it exists (compared with the model's name later)
    elif getattr(args, "actuator", None):
        from bench.rig.actuator import load
        desc = load(args.actuator)
        sign = desc.get("load_sign")      # the side a loaded play sits on (rig inject)
        args.load_sign = 1.0 if sign is None else float(sign)
        lead_m = desc.get("lead_m")
        if getattr(args, "lead_mm", None) is None:
            if lead_m is None:
                raise BenchError(f"{args.actuator}: the description gives no lead_m "
                                 "(use --lead-mm)")
            args.lead_mm = 1e3 * lead_m
            given = f"{args.actuator}: lead_m"
    lead = getattr(args, "lead_mm", None)
    lo, hi = LEAD_MM
    if lead is not None and not (math.isfinite(lead) and lo <= lead <= hi):
        raise BenchError(f"{given}: a ball-screw lead is {lo:g} to {hi:g} mm, got "
                         f"{lead:g} mm")
    alpha = getattr(args, "alpha", 0.05)
    if not (math.isfinite(alpha) and ALPHA[0] <= alpha < ALPHA[1]):
        raise BenchError(f"--alpha must be from {ALPHA[0]:g} to below {ALPHA[1]:g}, got "
                         f"{alpha:g}")
    seed = getattr(args, "seed", None)       # parsed in range; a namespace built in code
    if seed is not None and not opt.SEED_RANGE[0] <= seed <= opt.SEED_RANGE[1]:
        raise BenchError(f"--seed must be from {opt.SEED_RANGE[0]} to {opt.SEED_RANGE[1]} "
                         f"(numpy's and scikit-learn's generators), got {seed}")
    if getattr(args, "workers", None) is not None and args.workers < 1:
        raise BenchError("--workers must be >= 1")
    if getattr(args, "folds", None) is not None and args.folds < 2:
        raise BenchError("--folds must be >= 2")


def run(args: argparse.Namespace) -> int:
    cmd = getattr(args, "rig_command", None)
    if cmd is None:
        args.rig_parser.print_help()
        return 2
    _check(args)
    return {"baseline": _baseline, "assess": _assess, "study": _study,
            "inject": _inject, "train": _train, "classify": _classify}[cmd](args)


def _read(tables: list[str], runs: list[int] | None) -> list[Any]:
    from bench import BenchError
    from bench.rig.cycles import read_cycles
    cycles = []
    have: set[int] = set()
    lost: list[str] = []
    for t in tables:
        mine = read_cycles(t, skipped=lost)
        have |= {c.run for c in mine}
        cycles += [c for c in mine if runs is None or c.run in runs]
    for line in lost:                 # reported, never dropped silently
        print(line, file=sys.stderr)
    missing = sorted(set(runs or ()) - have)
    if not cycles or missing:
        what = missing or runs or []
        more = f" and {len(what) - 10} more" if len(what) > 10 else ""
        raise BenchError(f"no cycle of run(s) {','.join(map(str, what[:10]))}{more} in "
                         f"{', '.join(tables)} (they have run(s) "
                         f"{','.join(map(str, sorted(have)))})")
    return cycles


def _baseline(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.rig import update as U
    out = Path(args.out)
    check_output_file(out, "--out", (".json",))
    from bench.rig.model_io import inputs_guard
    inputs_guard([("--out", args.out)], [*args.tables, *([args.update] if args.update else [])])
    cycles = _read(args.tables, runs_list(args.runs, "--runs"))
    if args.update:
        from bench.rig.baseline import Baseline
        old = Baseline.load(args.update)
        if args.load_unit and old.load_unit and args.load_unit != old.load_unit:
            raise BenchError(f"--load-unit {args.load_unit}, but {args.update} is in "
                             f"{old.load_unit}")
        base, decisions = U.update(old, cycles, args.force, [Path(t).name for t in args.tables])
        for line in U.text(decisions):
            print(line)
        if base is old:
            print(f"nothing added; {out} not written")
            return 0
        notes: list[str] = []
    else:
        if args.force:
            raise BenchError("--force goes with --update")
        base, notes = U.build(cycles, [Path(t).name for t in args.tables], args.lead_mm,
                              _load_unit(cycles, args.load_unit), args.alpha)
    for line in notes:
        print(line)
    base.save(out)
    print(base.describe())
    for key, cal in base.thresholds.items():
        thr = ", ".join(f"{k} {v:.3g}" for k, v in cal["thresholds"].items())
        prov = "; provisional: fewer than 3 runs" if cal.get("provisional") else ""
        print(f"load {key}: thresholds (leave-one-run-out over runs "
              f"{','.join(map(str, cal['runs']))}, alpha {cal['alpha']:g}{prov}): {thr}")
    return 0


def _load_unit(cycles: list[Any], given: str | None) -> str:
    """The baseline's load unit: the traces' (their import map's), else `--load-unit`;
    one line when they disagree."""
    from bench import BenchError
    found = {c.load_unit for c in cycles if c.load_unit}
    if given and found - {given}:
        raise BenchError(f"--load-unit {given}, but the traces' loads are in "
                         f"{', '.join(sorted(found))}")
    if len(found) > 1:
        raise BenchError(f"the traces' loads come in several units ({', '.join(sorted(found))}): "
                         "build one baseline per unit")
    return given or (found.pop() if found else "")


def _assess(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.rig.baseline import Baseline
    from bench.rig.fallback import in_unit, match_load
    from bench.rig.features import cycle_features, verdict
    if args.json:
        check_output_file(args.json, "--json", stdout_ok=True)
    base = Baseline.load(args.baseline)
    cycles = _read(args.tables, runs_list(args.runs, "--runs"))
    verdicts: list[dict[str, Any]] = []
    counts: dict[tuple[str, float], tuple[int, int, int]] = {}
    notes: list[str] = []
    for c in cycles:
        # the baseline load that judges the cycle, as bench gap matches it (the unit of a
        # trace's load converted, the nearest load within 5 %, the only one if unknown)
        load, note = match_load(base, in_unit(c.load, c.load_unit, base.load_unit))
        if load is None:
            raise BenchError(f"{args.baseline}: {c.label}: {note}")
        if note and note not in notes:
            notes.append(note)
        c.load = load
        cal = base.thresholds.get(f"{load:g}")
        if cal is None:
            raise BenchError(f"{args.baseline}: no thresholds for load {base.load_text(load)} "
                             "(build the baseline from two or more healthy runs of that load)")
        f = cycle_features(base.for_load(load), c, base.lead_mm)
        v = verdict(base, f, cal["thresholds"])
        verdicts.append(v)
        key = (c.source, c.load)
        n, k, u = counts.get(key, (0, 0, 0))
        counts[key] = (n + int(v["judged"]), k + int(v["flagged"]), u + int(not v["judged"]))
        if not args.quiet:
            state = "FLAGGED" if v["flagged"] else ("ok" if v["judged"] else "NOT JUDGED")
            print(f"{c.label}: {state}: {v['verdict']}")
    for note in notes:
        print(f"note: {note}")
    if not args.quiet and verdicts:
        # one load judged: its baseline line; several: the baseline of every load
        against = {v["baseline"] for v in verdicts}
        print(f"against {verdicts[0]['baseline'] if len(against) == 1 else base.describe()}")
    for (src, load), (n, k, u) in sorted(counts.items()):
        rate = f"{100 * k / n:.0f} %" if n else "-"
        print(f"{src} load {load:g}: {k} / {n} cycles flagged ({rate})"
              + (f"; {u} incomplete cycle(s) not judged" if u else ""))
    if args.json:
        text = json.dumps(verdicts, indent=1, default=str)
        if args.json == "-":
            sys.stdout.write(text + "\n")
        else:
            Path(args.json).write_text(text)
    return 0


def _study(args: argparse.Namespace) -> int:
    from bench.cli.outputs import check_output_dir
    from bench.rig.report import write
    from bench.rig.study import run_study
    check_output_dir(args.out, "--out")
    if args.model:
        from bench.rig.model_io import load
        load(args.model)                      # a bad model fails before the work
    cal = runs_list(args.calibrate_runs, "--calibrate-runs") or []
    hold = runs_list(args.holdout_runs, "--holdout-runs") or []
    only = [x.strip() for x in args.only.split(",")] if args.only else None
    from bench.runtime.workers import session
    with session(args.workers, args.scheduler):     # one cluster for every condition
        study = run_study(args.directory, cal, hold, args.healthy, args.workers,
                          args.alpha, progress=sys.stderr.isatty(), conditions=only,
                          lead_mm=args.lead_mm, scheduler=args.scheduler,
                          model=args.model, supervised=not args.no_supervised)
    command = "bench rig " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["rig"] \
        else f"bench rig study {args.directory} --calibrate-runs {args.calibrate_runs} " \
             f"--holdout-runs {args.holdout_runs} --out {args.out}"
    paths = write(study, Path(args.out), command)
    print(paths["md"].read_text().split("![residual]")[0])
    print("written: " + ", ".join(str(p) for p in paths.values()))
    return 0


def _inject(args: argparse.Namespace) -> int:
    from bench.cli.outputs import check_output_dir
    from bench.rig.inject import run_cli
    check_output_dir(args.out, "--out")
    cal = runs_list(args.calibrate_runs, "--calibrate-runs") or []
    hold = runs_list(args.holdout_runs, "--holdout-runs") or []
    command = "bench rig " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["rig"] \
        else f"bench rig inject {' '.join(args.tables)} --calibrate-runs " \
             f"{args.calibrate_runs} --holdout-runs {args.holdout_runs} --out {args.out}"
    return run_cli(args, cal, hold, command)


def _read_all(path: str) -> list[Any]:
    """Every readable cycle of one table (what is not read is listed on stderr)."""
    from bench.rig.cycles import read_cycles
    lost: list[str] = []
    cycles = read_cycles(path, skipped=lost)
    for line in lost:
        print(line, file=sys.stderr)
    return cycles


def _train(args: argparse.Namespace) -> int:
    from bench.rig.model_io import run_train
    return run_train(args, _read_all)


def _classify(args: argparse.Namespace) -> int:
    from bench.rig.model_io import run_classify
    return run_classify(args, _read_all)
