"""`bench calibrate`: fit the nominal model's uncertain parameters to a healthy log, so
later logs of that actuator are diagnosed against its own baseline (issue 5)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    from bench.gap.calibrate import DEFAULT
    p = subparsers.add_parser(
        "calibrate", help="fit the nominal model to a healthy log",
        description="Fit the nominal model's uncertain parameters (inertia, friction level, "
                    "torque constant, lead, sensor gains, current offset) to a healthy log "
                    "by closed-loop least squares with a prior tolerance on each (fast plant "
                    "mode). The output is used by `bench gap --nominal`.")
    p.add_argument("log", metavar="HEALTHY", help="candump log (.log) or trace of a healthy run")
    p.add_argument("--model", default="plant", metavar="NAME",
                   help="nominal model to calibrate (plant)")
    p.add_argument("--params", metavar="A,B,...", default=",".join(DEFAULT),
                   help=f"parameters to calibrate (default: {','.join(DEFAULT)})")
    p.add_argument("--nominal", metavar="JSON",
                   help="start from these parameters (default: thesis values)")
    p.add_argument("--encoder", choices=("absolute", "relative"), default="absolute",
                   help="encoder angle reference (see bench gap --help)")
    p.add_argument("-o", "--output", metavar="CALIBRATION.json", default="calibration.json",
                   help="where to write the calibration (default calibration.json; '-': stdout)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.gap.calibrate import calibrate
    from bench.gap.inputs import load_log, load_nominal
    names = [n.strip() for n in args.params.split(",") if n.strip()]
    if not names:
        raise BenchError("--params lists no parameter")
    check_output_file(args.output, "-o", (".json",), stdout_ok=True)   # before the fit
    log = load_log(args.log)
    cal = calibrate(log, load_nominal(args.nominal), names, args.model, args.encoder)
    cal["log"] = str(args.log)
    text = json.dumps(cal, indent=1)
    if args.output == "-":
        print(text)
        return 0
    Path(args.output).write_text(text)
    g0, g1 = cal["gap_before"]["heldout_part"]["total"], cal["gap_after"]["heldout_part"]["total"]
    for k, v in cal["params"].items():
        lo, hi = cal["ci95"][k]
        print(f"{k:28s} {v:.6g}  (95 % CI {lo:.6g} .. {hi:.6g}; nominal "
              f"{cal['nominal'][k]:.6g})")
    print(f"held-out gap (RMS, x noise floor): {g0:.3g} -> {g1:.3g}")
    for n in cal["notes"]:
        print(f"note: {n}")
    print(f"calibration: {args.output}", file=sys.stderr)
    return 0
