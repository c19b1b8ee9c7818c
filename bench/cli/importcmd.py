"""`bench import`: a CSV/Parquet signal table from another rig -> the bench's signal table
at the SYNC rate (issue 5). See bench.gap.importer for the map format."""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "import", help="import a CSV/Parquet table from another rig",
        description="Map a table's columns to the bench's signals (column, unit, scale), "
                    "resample to the SYNC rate and save a trace (.npz/.csv/.parquet). "
                    "Map: JSON list of {signal, column, unit, scale[, wrap]} or object "
                    "signal -> column/entry, or CSV with header signal,column,unit,scale. "
                    "Signals: t_s, setpoint_position_m, setpoint_speed_rad_s, mode, "
                    "current_demand_a, current_a, motor_speed_rad_s, motor_angle_rad, "
                    "position_m, load_force_n (load cell). Units: time s/ms/us/ns/min, "
                    "length m/mm/um/in, speed rad/s/rpm/deg/s/rev/s, angle rad/deg/rev, "
                    "current A/mA, force N/kN/lbf, mode -.")
    p.add_argument("table", metavar="TABLE", help="CSV or Parquet table")
    p.add_argument("--map", required=True, metavar="MAP", help="column map (.json or .csv)")
    p.add_argument("-o", "--output", metavar="OUT",
                   help="output trace (.npz, .csv or .parquet; default TABLE.npz)")
    p.add_argument("--sync-period", type=float, default=1e-3, metavar="S",
                   help="SYNC period to resample to (s, default 0.001)")
    p.add_argument("--source-rate", type=float, metavar="HZ",
                   help="the table's fixed sample rate when it has no time column")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.gap.importer import import_table, read_map
    if args.source_rate is not None and not (math.isfinite(args.source_rate)
                                             and args.source_rate > 0):
        raise BenchError("--source-rate must be a finite rate > 0 Hz")
    out = Path(args.output) if args.output else Path(args.table).with_suffix(".npz")
    check_output_file(out, "-o", (".npz", ".csv", ".parquet"))    # before the import
    mapping = read_map(args.map)
    tr = import_table(args.table, mapping, args.sync_period, args.source_rate)
    tr.save(out)
    missing = [s for s in ("setpoint_position_m", "mode", "current_a", "motor_speed_rad_s",
                           "motor_angle_rad", "position_m", "current_demand_a")
               if s not in tr]
    print(f"{out}: {len(tr)} samples at {1 / args.sync_period:g} Hz, "
          f"{len(tr) * args.sync_period:.3g} s; signals: "
          + ", ".join(k for k in tr.columns if k != "t_s"))
    if missing:
        print("not mapped (bench gap needs a set-point, mode and the four sensors): "
              + ", ".join(missing))
    from bench.bus.logs import integrity
    for line in integrity(tr.meta):
        print(f"{out}: {line}")
    return 0
