"""`bench decode FILE.log`: a bus log (candump, .asc, .blf, .trc, .mf4) to a table of signals
through the DBC."""

from __future__ import annotations

import argparse
import sys

from bench import BenchError
from bench.cli import options as opt

LOG_SUFFIXES = (".log", ".asc", ".blf", ".trc", ".mf4")


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = opt.add_command(sub, "decode", "decode a bus log into a signal table (CSV/Parquet)", """
        Decode a bus log (candump .log; .asc, .blf, .trc, .mf4 through python-can; each also
        .gz/.xz/.bz2-compressed, decompressed as it is read) through
        dbc/ema.dbc into one row per SYNC period (set-points, demand, current, encoder, LVDT,
        temperature, status). The SYNC period and encoder resolution come from the SDO traffic
        in the log when present. Bad lines are counted and the first ones reported with their
        line numbers; the rest is kept. Lost SYNCs, frames missing from a period, duplicates and
        frames out of time order are counted and printed. Exit status 2 when nothing can be
        decoded (no SYNC period).""")
    p.add_argument("file", metavar="FILE.log", help="bus log (.log, .asc, .blf, .trc, .mf4; "
                   "also .gz/.xz/.bz2-compressed); "
                   "'-': standard input (candump -L unless --format says otherwise), e.g. "
                   "`candump -L can0 | bench decode - -o -`")
    opt.add_output(p, help="write the table (.csv, .parquet or .npz; '-': CSV on standard "
                        "output, the summary then on standard error); default: print a "
                        "summary")
    p.add_argument("--format", choices=[s[1:] for s in LOG_SUFFIXES], default=None,
                   help="the log's format where its name does not say it (standard input, "
                        "a file without a known suffix); default: the suffix")
    opt.add_node_id(p)
    p.add_argument("--period", type=float, default=None, metavar="S",
                   help="SYNC period in s, within the bench's range (sim.sync_period_s); "
                        "default: the log's own (its SDO 0x1006, else its SYNC time "
                        "stamps), else 0.001. Given, it is used, with a note when the "
                        "log's SDO traffic shows another")
    p.add_argument("--counts-per-rev", type=int, default=None, metavar="N",
                   help="encoder resolution if the log does not show it (default 16384)")
    p.set_defaults(func=run)


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse, before the log is read, a period or resolution no log can have and an
    output that cannot be written. The period's range is the bench's SYNC period's
    (parameter sim.sync_period_s, object 0x2008 sub 1: 0.1 to 100 ms); a log's times
    past it overflow or say nothing."""
    import math

    from bench.cli.outputs import check_output_file
    from plant_rt.params import resolve
    if args.period is not None and not (math.isfinite(args.period) and args.period > 0):
        raise BenchError(f"--period must be a finite number of seconds > 0, not "
                         f"{args.period:g}")
    info = resolve("sim.sync_period_s")
    lo, hi = float(info.min or 0.0), float(info.max or math.inf)
    if args.period is not None and not lo <= args.period <= hi:
        raise BenchError(f"--period {args.period:g} s is outside the bench's SYNC period "
                         f"range, {lo:g} to {hi:g} s ({info.name})")
    if args.counts_per_rev is not None and args.counts_per_rev < 1:
        raise BenchError(f"--counts-per-rev must be >= 1, not {args.counts_per_rev}")
    if args.output:
        check_output_file(args.output, "-o", (".csv", ".parquet", ".npz"), stdout_ok=True)


def period_note(args: argparse.Namespace, tr) -> str:
    """What to say when --period differs from the SYNC period the log's SDO traffic shows
    ("" when none is given, the log shows none, or they agree). A given --period is used:
    it is how a log whose SDO traffic is wrong, or of another run, is read (docs/bus.md)."""
    own = (tr.meta.get("clock") or {}).get("sdo_period_s")
    if args.period is None or own is None or abs(own - args.period) <= 1e-9 * own:
        return ""
    return (f"--period {args.period * 1e3:g} ms is used, not the SYNC period of "
            f"{own * 1e3:g} ms the log's SDO traffic gives")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from bench.bus.logread import LogIssues, report_issues
    from bench.bus.logs import trace_from_log
    from bench.signals.integrity import integrity

    check_arguments(args)
    to_stdout = args.output == "-"
    say = sys.stderr if to_stdout else sys.stdout       # stdout is the table's then
    name = "<stdin>" if args.file == "-" else args.file
    issues = LogIssues(20)
    tr = trace_from_log(args.file, args.node_id, args.period, args.counts_per_rev, issues,
                        fmt=args.format)
    for line in report_issues(issues):
        print(f"{name}: {line}", file=sys.stderr)
    note = period_note(args, tr)
    if note:
        print(f"{name}: note: {note}", file=sys.stderr)
    m = tr.meta
    src = (m.get("clock") or {}).get("source", "default")
    print(f"{name}: {m['frames']} frames, {len(tr)} SYNC periods of {m['period_s'] * 1e3:g} "
          f"ms ({'the default' if src == 'default' else src}), {m['runs']} run(s), {m['bad_frames']} bad frames, {m['sync_gaps']} lost SYNCs, "
          f"{len(issues)} bad lines, {m['emcy_count']} EMCY, "
          f"{len(m['params_from_sdo'])} parameters from SDO", file=say)
    found = integrity(m)
    print(f"{name}: " + ("; ".join(found) if found else
                         "no lost, missing, duplicate or out-of-order frame"), file=say)
    if m.get("short_frames"):
        print(f"{name}: {m['short_frames']} frames shorter than dbc/ema.dbc "
              "describes (an older frame layout): their signals that fit were decoded, the "
              "columns of the missing ones are empty", file=say)
    if to_stdout:
        tr.write_csv(sys.stdout)
    elif args.output:
        tr.save(args.output)
        print(f"wrote {args.output} ({len(tr)} rows, {len(tr.columns)} columns)")
    else:
        pos, cur = tr["position_m"], tr["current_a"]
        if np.isfinite(pos).any() and np.isfinite(cur).any():
            print(f"position {np.nanmin(pos) * 1e3:.3f} .. {np.nanmax(pos) * 1e3:.3f} mm, "
                  f"current {np.nanmin(cur):.2f} .. {np.nanmax(cur):.2f} A")
    return 0
