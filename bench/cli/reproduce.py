"""`bench reproduce`: thesis chapter 5 rows P1-P9, side by side, with figures.

Everything goes to ``--out`` (default ``out/reproduce/``): ``reproduction.md``, its
figures in ``figures/`` and, with ``--json``, the rows. The repository's own page is
regenerated only when asked: ``--doc docs/reproduction.md`` writes the page there and
its figures into ``docs/figures/``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import textwrap
import time
from pathlib import Path

from bench import BenchError, machine_description
from bench.cli import options as opt

PAGE = "reproduction.md"


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reproduce", help="reproduce thesis chapter 5 (P1-P9) side by side",
                       description="Run rows P1-P9 of seed-targets.md on the full-fidelity "
                       "plant and write a table of thesis value, project value and ratio "
                       f"({PAGE} and figures/ in --out; the repository's page only with "
                       "--doc).")
    opt.add_out(p, f"folder for {PAGE} and figures/ (default: %(default)s)",
                default="out/reproduce")
    opt.add_json(p, "also write the rows as JSON")
    opt.add_figures(p, "folder for the PNG figures (default: OUT/figures; '' for none)")
    opt.add_doc(p, "also write the page to PATH (the repository's: docs/reproduction.md) "
                        "and its figures into PATH's folder's figures/")
    p.add_argument("--only", metavar="GROUP", action="append",
                   choices=["P1-P3", "P4", "P5-P7", "P8", "P9"],
                   help="run only these row groups (repeatable)")
    opt.add_set(p, "override a plant parameter (see `bench plant --list-params`)")
    p.set_defaults(func=run)


def check_outputs(args: argparse.Namespace) -> None:
    """--out, --json, --figures and --doc, checked before the run (nothing is made)."""
    from bench.cli import outputs
    if args.figures is None:
        args.figures = str(Path(args.out) / "figures")
    outputs.check_outputs(args, dirs=("out",))
    outputs.check_outputs(args, files=("json",), dirs=("figures",), make_parents=False)
    if args.doc:
        outputs.check_output_file(args.doc, "--doc", (".md",), make_parents=False)
        if args.figures:
            outputs.check_output_dir(Path(args.doc).parent / "figures", "--doc")


def _page(res, elapsed: float, figures: list[Path], page: Path, command: str) -> str:
    from bench.studies import reproduce as R
    text = R.markdown(res, machine_description(), command)
    text += f"\nWall time of the run: {elapsed:.1f} s.\n"
    if figures:
        base = page.parent.resolve()
        rel = [Path(p).resolve().relative_to(base) if Path(p).resolve().is_relative_to(base)
               else Path(p).resolve() for p in figures]
        text += "\n" + "\n".join(f"![{p.stem}]({p.as_posix()})" for p in rel) + "\n"
    return text


def run(args: argparse.Namespace) -> int:
    from bench.studies import reproduce as R
    from plant_rt.params import ParameterError, PlantParams
    try:
        params = PlantParams().with_assignments(args.set)
    except ParameterError as exc:
        raise BenchError(str(exc)) from None
    check_outputs(args)
    t0 = time.perf_counter()
    res = R.run(params, only=args.only, progress=True)
    elapsed = time.perf_counter() - t0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    figs = R.figures(res, args.figures) if args.figures else []
    written = [out / PAGE]
    written[0].write_text(_page(res, elapsed, figs, written[0], "bench reproduce"))
    if args.doc:
        doc = Path(args.doc)
        doc_figs = []
        if figs:
            (doc.parent / "figures").mkdir(exist_ok=True)
            doc_figs = [Path(shutil.copy2(f, doc.parent / "figures" / Path(f).name))
                        for f in figs]
        doc.write_text(_page(res, elapsed, doc_figs, doc, f"bench reproduce --doc {doc}"))
        written += [doc, *doc_figs]
    if args.json:
        Path(args.json).write_text(json.dumps([R.row_json(r) for r in res.rows], indent=2))
        written.append(Path(args.json))
    print(terminal_table(res.rows))
    for p in written + figs:
        print(f"wrote {p}", file=sys.stderr)
    return 0


COLUMNS = (("id", 4), ("quantity", 44), ("unit", 6), ("thesis", 14), ("project", 14),
           ("ratio", 6))
"""The terminal table's columns and their widths; longer cells wrap, none is cut."""


def terminal_table(rows) -> str:
    """The rows as a table for the terminal: a header with units, every value whole
    (long cells wrap onto the next lines)."""
    from bench.studies.reproduce import value_text as fmt
    head = "  ".join(f"{name:<{w}}" if k < 3 else f"{name:>{w}}"
                     for k, (name, w) in enumerate(COLUMNS))
    lines = [head, "  ".join("-" * w for _, w in COLUMNS)]
    for r in rows:
        ratio = "" if r.ratio != r.ratio else f"{r.ratio:.3f}"
        cells = [r.id, r.quantity, r.unit, fmt(r.thesis), fmt(r.project), ratio]
        wrapped = [textwrap.wrap(str(c), w) or [""] for c, (_, w) in zip(cells, COLUMNS,
                                                                         strict=True)]
        for k in range(max(len(w) for w in wrapped)):
            lines.append("  ".join(
                (f"{w[k]:<{cw}}" if j < 3 else f"{w[k]:>{cw}}") if k < len(w) else " " * cw
                for j, (w, (_, cw)) in enumerate(zip(wrapped, COLUMNS, strict=True)))
                .rstrip())
    return "\n".join(lines)
