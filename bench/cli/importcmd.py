"""`bench import`: a CSV/Parquet signal table from another rig -> the bench's signal table.
See bench.gap.importer for the map format."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from bench.cli import options as opt
from bench.signals import units

if TYPE_CHECKING:
    from bench.signals.trace import Trace

FORMATS = ("parquet", "npz", "csv")


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    p = opt.add_command(subparsers, "import", "import a CSV/Parquet table from another rig", """
        Map a table's columns to the bench's signals (column, unit, scale, optional 'minus'
        column) and save a trace (.npz/.csv/.parquet) at the table's own sample instants
        (nothing interpolated), or resampled to a SYNC period with --sync-period. --split-by
        cuts a table holding many runs into one trace per run, named after its keys. Map: JSON
        list of {signal, column, unit, scale[, wrap, minus]} or object signal -> column/entry,
        or CSV with header signal,column,unit,scale[,wrap,minus]. Signals: t_s,
        setpoint_position_m, setpoint_speed_rad_s, mode, current_demand_a, current_a,
        motor_speed_rad_s, motor_angle_rad, position_m, load_force_n (load cell). Units:
        """ + units.summary() + ".")
    p.add_argument("table", metavar="TABLE",
                   help="CSV (also .csv.xz/.gz/.bz2) or Parquet table")
    p.add_argument("--map", required=True, metavar="MAP", help="column map (.json or .csv)")
    opt.add_output(p, help="output trace (.npz, .csv or .parquet; default TABLE.npz); with "
                        "--split-by a directory (default: TABLE's name without suffixes)")
    p.add_argument("--split-by", metavar="COL,COL,...",
                   help="one trace per combination of these columns' values, named "
                        "COL=VALUE_COL=VALUE.FORMAT, e.g. load,run,group")
    p.add_argument("--format", choices=FORMATS, default="parquet",
                   help="file format of the split traces (default parquet)")
    p.add_argument("--sync-period", type=float, default=None, metavar="S",
                   help="resample to this SYNC period (s); default: keep the table's "
                        "own sample instants")
    p.add_argument("--source-rate", type=float, metavar="HZ",
                   help="the table's fixed sample rate when it has no time column")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.core.filenames import check_not_input
    from bench.gap.importer import import_table, read_map
    if args.source_rate is not None and not (math.isfinite(args.source_rate)
                                             and 1e-3 <= args.source_rate <= 1e6):
        raise BenchError("--source-rate must be a rate from 0.001 Hz to 1 MHz (a sample "
                         "every 1000 s to every 1 us)")
    if args.sync_period is not None and not (math.isfinite(args.sync_period)
                                             and 1e-5 <= args.sync_period <= 1.0):
        raise BenchError("--sync-period must be between 1e-05 and 1 s")
    if args.split_by is not None:
        return _split(args)
    out = Path(args.output) if args.output else Path(args.table).with_suffix(".npz")
    check_output_file(out, "-o", (".npz", ".csv", ".parquet"))    # before the import
    check_not_input(out, "-o")               # the default TABLE.npz too
    mapping = read_map(args.map)
    tr = import_table(args.table, mapping, args.sync_period, args.source_rate)
    tr.save(out)
    _describe(out, tr)
    _availability(tr)
    return 0


def _availability(tr: Trace) -> None:
    """What the bench can do with such a trace, consumer by consumer (bench.gap.needs)."""
    from bench.gap.needs import describe
    print("what this log supports (bench.gap.needs):")
    for line in describe(tr):
        print(f"  {line}")


def _split(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_dir
    from bench.gap.importer import read_map, split_table
    keys = [k.strip() for k in args.split_by.split(",") if k.strip()]
    if not keys:
        raise BenchError("--split-by names no column")
    name = Path(args.table).name.split(".")[0] or "split"
    outdir = Path(args.output) if args.output else Path(args.table).parent / name
    if outdir.exists() and not outdir.is_dir():
        raise BenchError(f"-o {outdir}: not a directory (with --split-by, -o is a directory)")
    check_output_dir(outdir, "-o")                   # before the import
    mapping = read_map(args.map)
    parts = split_table(args.table, mapping, keys, args.sync_period, args.source_rate)
    paths = _split_paths(outdir, [stem for stem, _ in parts], args.format)
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BenchError(f"-o {outdir}: cannot create the directory ({exc.strerror})") from None
    for i, ((_, tr), path) in enumerate(zip(parts, paths, strict=True)):
        try:
            tr.save(path)
        except OSError as exc:
            raise BenchError(f"-o {outdir}: cannot write {path.name} "
                             f"({exc.strerror or exc})") from None
        if i < 3:
            _describe(path, tr)
    dts = sorted({round(float(tr.meta["sample_period_s"]), 9) for _, tr in parts})
    print(f"{outdir}: {len(parts)} traces split by {', '.join(keys)}; sample period(s) "
          + ", ".join(f"{d * 1e3:g} ms" for d in dts))
    _availability(parts[0][1])
    return 0


def _split_paths(outdir: Path, stems: list[str], fmt: str) -> list[Path]:
    """The split traces' files in `outdir`, named from their keys through
    `bench.core.filenames.data_file` (inside `outdir`, none of them an input), checked all
    before the first is written; BenchError if two would be one file."""
    from bench import BenchError
    from bench.core.filenames import data_file
    paths = [data_file(outdir, stem, f".{fmt}") for stem in stems]
    seen: dict[Path, str] = {}
    for stem, path in zip(stems, paths, strict=True):
        if path in seen:
            raise BenchError(f"--split-by: the runs {seen[path]} and {stem} would both be "
                             f"written to {path}")
        seen[path] = stem
    return paths


def _describe(out: Path, tr: Trace) -> None:
    """One line of what was imported, what is missing and what the table lost."""
    dt = float(tr.meta["sample_period_s"])
    how = "resampled to" if tr.meta.get("resampled") else "as sampled,"
    print(f"{out}: {len(tr)} samples {how} {1 / dt:g} Hz, {float(tr.t[-1]) + dt:.3g} s; "
          "signals: " + ", ".join(k for k in tr.columns if k != "t_s"))
    missing = [s for s in ("setpoint_position_m", "mode", "current_a", "motor_speed_rad_s",
                           "motor_angle_rad", "position_m", "current_demand_a")
               if s not in tr]
    if missing:
        print("not mapped: " + ", ".join(missing))
    from bench.signals.integrity import integrity
    for line in integrity(tr.meta):
        print(f"{out}: {line}")
