"""`bench usage LOG_OR_TRACE...`: the usage of each run and per actuator (docs/usage.md).

    bench usage run1.log run2.log [--by-actuator] [--json OUT.json] [--plot DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from bench import BenchError
from bench.cli import options as opt


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = opt.add_command(
        sub, "usage",
        "usage monitoring: travel, reversals, cycles, load spectrum, life used", """
        The usage of each run from its candump log or saved trace: nut travel and screw
        revolutions, reversals, rainflow-counted position and load cycles (ASTM E1049), the load
        spectrum, the equivalent dynamic axial load F_m and the rating life consumed against the
        screw's dynamic load rating C_a (ISO 3408-5, Palmgren-Miner), time at winding
        temperature, I2t and time per motion regime; accumulated per actuator by the serial
        number the ECU read from object 0x1018 (docs/usage.md).""")
    p.add_argument("files", nargs="+", metavar="LOG_OR_TRACE",
                   help="candump .log ('-': candump -L on standard input), or a trace "
                        "saved by bench run --save (.npz, .csv, .parquet)")
    p.add_argument("--by-actuator", action="store_true",
                   help="also print the runs accumulated per actuator (serial number)")
    opt.add_json(p, "write every run and every actuator", metavar="OUT.json")
    p.add_argument("--plot", metavar="DIR",
                   help="write a PNG per run and per actuator: load spectrum, rainflow "
                        "matrices")
    p.add_argument("--preload", choices=["none", "double-nut"], default="none",
                   help="how the nut loads follow from the measured load (default: "
                        "%(default)s; docs/usage.md)")
    p.add_argument("--preload-n", type=float, default=None, metavar="N",
                   help="double-nut preload (default: the run's effects.preload_n)")
    opt.add_set(p, "a usage setting, e.g. usage.reversal_hysteresis_m=5e-6 (repeatable; "
                "docs/usage.md)", dest="assignments")
    p.add_argument("--load-rating-n", type=float, default=None, metavar="N",
                   help="dynamic load rating C_a (default: the run's "
                        "screw.dynamic_load_rating_n)")
    p.set_defaults(func=run)


def _check(args: argparse.Namespace) -> None:
    from bench.cli.outputs import check_output_dir, check_output_file
    if args.preload_n is not None and not (math.isfinite(args.preload_n)
                                           and args.preload_n >= 0):
        raise BenchError(f"--preload-n must be a finite number of newtons >= 0, not "
                         f"{args.preload_n:g}")
    if args.load_rating_n is not None and not (math.isfinite(args.load_rating_n)
                                               and args.load_rating_n > 0):
        raise BenchError(f"--load-rating-n must be a finite number of newtons > 0, not "
                         f"{args.load_rating_n:g}")
    if args.json:
        check_output_file(args.json, "--json", (".json",))
    if args.plot:
        check_output_dir(args.plot, "--plot")
    if args.files.count("-") > 1:
        raise BenchError("standard input (-) can be given once")
    for f in args.files:
        if f != "-" and Path(f).is_dir():
            raise BenchError(f"{f} is a directory, not a log (name the log files in it)")
        if f != "-" and not Path(f).exists():
            raise BenchError(f"no such file: {f}")
        if f != "-" and not Path(f).is_file():
            raise BenchError(f"{f}: not a regular file (a device or a pipe: give - to read "
                             "a log from standard input)")


def _settings(args: argparse.Namespace, cls):
    """The usage settings: --preload, --preload-n, then every --set NAME=VALUE."""
    from bench.signals.trace import is_number
    values: dict = {"preload_mode": args.preload,
                    "preload_n": -1.0 if args.preload_n is None else args.preload_n}
    known = {i.leaf: i for i in cls.infos()}
    for a in args.assignments:
        name, sep, value = a.partition("=")
        leaf = name.strip().removeprefix("usage.")
        if not sep or leaf not in known:
            raise BenchError(f"--set {a!r}: expected NAME=VALUE with NAME one of "
                             + ", ".join(f"usage.{k}" for k in known))
        values[leaf] = value.strip() if known[leaf].type is str else float(value) \
            if is_number(value) else value
    return cls.from_dict(values)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from bench.bus.logs import load_trace
    from bench.core.filenames import distinct_labels
    from bench.usage import UsageSettings, accumulate, usage_of_trace
    from bench.usage.accumulator import trace_params
    from bench.usage.table import format_table, notes

    _check(args)
    settings = _settings(args, UsageSettings)
    runs = []
    for f in tqdm(args.files, desc="usage", unit="file", file=sys.stderr,
                  disable=len(args.files) < 2 or not sys.stderr.isatty()):
        tr = load_trace(f)
        params = trace_params(tr)
        if args.load_rating_n is not None:
            params = params.with_dict({"screw.dynamic_load_rating_n": args.load_rating_n})
        runs.append((f, usage_of_trace(tr, settings, params)))
    labels = distinct_labels([f for f, _ in runs])
    stems = distinct_labels([Path(f).with_suffix("") for f, _ in runs])     # figure names
    print(format_table([(lab, s) for lab, (_, s) in zip(labels, runs, strict=True)]))
    for lab, (_, s) in zip(labels, runs, strict=True):
        for line in notes(lab, s):
            print(line)
    per_actuator = accumulate([s for _, s in runs])
    if args.by_actuator:
        print()
        print(format_table([(f"actuator {k}", s) for k, s in per_actuator.items()]))
        for k, s in per_actuator.items():
            for line in notes(f"actuator {k}", s):
                print(line)
    if args.json:
        doc = {"settings": settings.to_dict(),
               "runs": [{"file": str(f), **s.to_json()} for f, s in runs],
               "actuators": {k: s.to_json() for k, s in per_actuator.items()}}
        Path(args.json).write_text(json.dumps(doc, indent=1))
        print(f"wrote {args.json}")
    if args.plot:
        _plots(args.plot, list(zip(labels, stems, runs, strict=True)), per_actuator)
    return 0


def _plots(directory: str, runs, per_actuator) -> None:
    """A figure per run (`runs`: (label, stem, (file, summary))) and per actuator, each
    named through `bench.core.filenames.data_file` (``STEM_usage.png``, ``actuator_S_usage.png``:
    inside `directory`, distinct for distinct runs and serial numbers)."""
    from bench.core.filenames import data_file
    from bench.usage.figure import save_usage_figure
    out = Path(directory)
    figures = [(data_file(out, f"{stem}_usage", ".png"), s,
                f"{label}: actuator {s.actuator_serial}") for label, stem, (_, s) in runs]
    figures += [(data_file(out, f"actuator_{k}_usage", ".png"), s,
                 f"actuator {k}: {s.runs:g} run(s)") for k, s in per_actuator.items()]
    out.mkdir(parents=True, exist_ok=True)
    for path, s, title in figures:
        save_usage_figure(s, title, path)
    written = {p for p, _, _ in figures}
    print(f"wrote {len(written)} figure(s) into {out}")
