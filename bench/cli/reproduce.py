"""`bench reproduce`: thesis chapter 5 rows P1-P9, side by side, with figures."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from bench import BenchError, machine_description


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reproduce", help="reproduce thesis chapter 5 (P1-P9) side by side",
                       description="Run rows P1-P9 of seed-targets.md on the full-fidelity "
                       "plant and write a table of thesis value, project value and ratio.")
    p.add_argument("--out", default="docs/reproduction.md",
                   help="markdown report to write (default: %(default)s)")
    p.add_argument("--json", metavar="PATH", help="also write the rows as JSON")
    p.add_argument("--figures", metavar="DIR", default="docs/figures",
                   help="directory for PNG figures (default: %(default)s; '' for none)")
    p.add_argument("--only", metavar="GROUP", action="append",
                   choices=["P1-P3", "P4", "P5-P7", "P8", "P9"],
                   help="run only these row groups (repeatable)")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="override a plant parameter (see `bench plant --list-params`)")
    p.set_defaults(func=run)


def check_outputs(args: argparse.Namespace) -> None:
    """--out (its directories made), --json and --figures, checked before the run."""
    from bench.cli import outputs
    outputs.check_outputs(args, files=("out",))
    outputs.check_outputs(args, files=("json",), dirs=("figures",), make_parents=False)


def run(args: argparse.Namespace) -> int:
    from bench import reproduce as R
    from plant_rt.params import ParameterError, PlantParams
    try:
        params = PlantParams().with_assignments(args.set)
    except ParameterError as exc:
        raise BenchError(str(exc)) from None
    check_outputs(args)
    t0 = time.perf_counter()
    res = R.run(params, only=args.only, progress=True)
    elapsed = time.perf_counter() - t0
    text = R.markdown(res, machine_description())
    text += f"\nWall time of the run: {elapsed:.1f} s.\n"
    if args.figures:
        paths = R.figures(res, args.figures)
        out_dir = Path(args.out).parent if args.out else Path(".")
        rel = [Path(p).resolve().relative_to(out_dir.resolve())
               if Path(p).resolve().is_relative_to(out_dir.resolve()) else Path(p)
               for p in paths]
        text += "\n" + "\n".join(f"![{p.stem}]({p.as_posix()})" for p in rel) + "\n"
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
        print(f"wrote {args.out}")
    if args.json:
        Path(args.json).write_text(json.dumps([r.to_json() for r in res.rows], indent=2))
        print(f"wrote {args.json}")
    # the table on the terminal too
    for r in res.rows:
        ratio = "" if r.ratio != r.ratio else f"{r.ratio:6.3f}"
        print(f"{r.id:4s} {r.quantity[:58]:58s} {str(r.thesis)[:14]:>14s} "
              f"{str(r.project)[:14]:>14s} {ratio}")
    return 0
