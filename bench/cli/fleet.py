"""`bench fleet`: the fleet store of many actuators' ground tests (docs/fleet.md).

    bench fleet ingest PATH...   logs (candump, trace tables), directories, globs -> store
    bench fleet status           one line per actuator: last test, level, trend, RUL, usage
    bench fleet report --out D   HTML overview (what to inspect this week) + actuator pages
    bench fleet export --out D   every table as Parquet
    bench fleet synth --out D    a synthetic fleet of ground-test candump logs
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bench import BenchError
from bench.cli import options as opt


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = opt.add_command(
        sub, "fleet",
        "fleet store: ingest logs, status, report, export, synthetic fleet", """
        Many actuators' ground-test logs in one DuckDB store: health indexes, verdict and usage
        per run; status, HTML report, Parquet export; a synthetic fleet generator
        (docs/fleet.md).""")
    s = p.add_subparsers(title="fleet commands", dest="fleet_command", metavar="COMMAND")
    p.set_defaults(func=lambda a: _no_sub(p))

    from bench.fleet.store import default_db

    def db(q: argparse.ArgumentParser) -> None:
        q.add_argument("--db", default=str(default_db()), help="the store (default: "
                       "$BENCH_FLEET_DB, else fleet.duckdb)")

    def pool(q: argparse.ArgumentParser) -> None:
        opt.add_workers(q)
        opt.add_scheduler(q, "a Dask scheduler address to send the work to (default: "
                          "$BENCH_DASK_SCHEDULER, else a LocalCluster on 127.0.0.1)")

    q = opt.add_command(s, "ingest", "ingest logs into the store", """
        Read bus logs (candump .log, .asc, .blf, .trc, .mf4; each also .gz/.xz/.bz2) and
        trace tables (files, directories searched recursively, globs),
        grade each run with the HUMS and store it keyed by actuator, run time and log digest.
        Idempotent (a log already stored is skipped) and resumable (interrupted: run it again).""")
    q.add_argument("paths", nargs="+", metavar="PATH")
    db(q)
    pool(q)
    q.add_argument("--actuator", metavar="ID", default=None,
                   help="actuator id for logs that carry none (default: the name of the "
                   "log's directory)")
    q.set_defaults(func=run_ingest)

    q = opt.add_command(s, "status", "one line per actuator", """
        Per actuator: last test, level, Ci trend per day, RUL with its band, usage consumed.""")
    db(q)
    q.add_argument("--sort", choices=["id", "urgency"], default="id",
                   help="order of the lines (default: %(default)s)")
    q.add_argument("--trend-tests", type=int, default=10, metavar="N",
                   help="tests the Ci trend is fitted over, the last ones (default: "
                   "%(default)s)")
    q.add_argument("--as-of", metavar="TIME", default=None,
                   help="the status as it was then: only tests up to TIME count (ISO "
                   "8601, UTC; a date alone is the end of that day)")
    q.set_defaults(func=run_status)

    q = opt.add_command(s, "report", "HTML report: what to inspect this week, per actuator", """
        Static HTML with PNG figures: an overview (actuators to inspect this week, why, most
        urgent first) and one page per actuator.""")
    db(q)
    opt.add_out(q, "output folder", required=True)
    q.set_defaults(func=run_report)

    q = opt.add_command(s, "export", "every table as Parquet", """
        Write runs.parquet, failures.parquet and meta.parquet.""")
    db(q)
    opt.add_out(q, "output folder", required=True)
    q.set_defaults(func=run_export)

    q = opt.add_command(s, "synth", "a synthetic fleet of ground-test logs", """
        N actuators x D days of daily ground tests (the thesis' 2 Hz sine), each actuator with
        its own wear (driven by its own flights by default), simulated in-process and written as
        candump logs in OUT/<actuator>/.""")
    q.add_argument("--actuators", type=int, required=True, metavar="N")
    q.add_argument("--days", type=int, required=True, metavar="D")
    opt.add_out(q, "output folder", required=True)
    opt.add_seed(q, 0)
    q.add_argument("--wear", choices=["use", "time"], default="use",
                   help="use: wear driven by each actuator's flights (life consumed, "
                   "ISO 3408-5 L10 with Palmgren-Miner); time: the thesis' schedule in "
                   "days (default: %(default)s; docs/fleet.md)")
    pool(q)
    q.set_defaults(func=run_synth)


def _no_sub(p: argparse.ArgumentParser) -> int:
    p.print_help()
    return 2


def _db(args: argparse.Namespace) -> str:
    from bench.fleet.store import default_db
    return str(args.db or default_db())


def _workers(args: argparse.Namespace) -> int | None:
    if args.workers is not None and args.workers < 1:
        raise BenchError("--workers must be at least 1")
    return args.workers


def run_ingest(args: argparse.Namespace) -> int:
    from bench.fleet.ingest import ingest
    if args.actuator is not None and (not args.actuator.strip()
                                      or not args.actuator.isprintable()):
        raise BenchError(f"--actuator {args.actuator!r}: an actuator id is printable text "
                         "(no newline, tab or control character) and not blank")
    res = ingest(args.paths, _db(args), _workers(args), args.scheduler, args.actuator)
    rate = (res.stored + res.failed) / res.elapsed_s if res.elapsed_s > 0 else 0.0
    before = (f" ({res.failed_before} of them failed before: table `failures`, delete a "
              "row to retry)" if res.failed_before else "")
    print(f"{res.files} files: {res.skipped} already stored{before}, {res.stored} runs "
          f"stored, {res.failed} failed, in {res.elapsed_s:.1f} s ({rate:.2f} logs/s) -> "
          f"{_db(args)}")
    from bench.core.filenames import one_line
    for path, err in res.failures[:20]:
        err = err.removeprefix(f"{path}: ").removeprefix(f"{Path(path).name}: ")
        print(f"  failed: {one_line(path)}: {one_line(err)}", file=sys.stderr)
    if len(res.failures) > 20:
        print(f"  ... and {len(res.failures) - 20} more (table `failures`)", file=sys.stderr)
    return 0


def run_status(args: argparse.Namespace) -> int:
    from bench.fleet.status import fleet_status, format_table, parse_as_of, urgency
    from bench.fleet.store import Store
    if args.trend_tests < 2:
        raise BenchError("--trend-tests must be at least 2")
    as_of = parse_as_of(args.as_of) if args.as_of is not None else None
    t0 = time.perf_counter()
    with Store(_db(args), read_only=True) as store:
        rows = fleet_status(store, args.trend_tests, as_of)
        n_fail = len(store.failures())
    if args.sort == "urgency":
        rows.sort(key=urgency)
    if not rows:
        print("no runs in the store" + (f" up to {args.as_of}" if as_of is not None else ""))
        return 0
    print(format_table(rows))
    print(f"{len(rows)} actuators, {sum(r.tests for r in rows)} runs, {n_fail} failed logs "
          f"({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def run_report(args: argparse.Namespace) -> int:
    from bench.cli.outputs import check_output_dir
    from bench.fleet.report import write_report
    from bench.fleet.store import Store
    check_output_dir(args.out, "--out")
    with Store(_db(args), read_only=True) as store:
        page = write_report(store, args.out)
    print(f"report: {page}")
    return 0


def run_export(args: argparse.Namespace) -> int:
    from bench.cli.outputs import check_output_dir
    from bench.fleet.store import Store
    check_output_dir(args.out, "--out")
    with Store(_db(args), read_only=True) as store:
        paths = store.export(args.out)
    for p in paths:
        print(p)
    return 0


def run_synth(args: argparse.Namespace) -> int:
    from bench.cli.outputs import check_output_dir
    from bench.fleet.synth import synth
    if args.actuators < 1 or args.days < 1:
        raise BenchError("--actuators and --days must be at least 1")
    check_output_dir(args.out, "--out")
    t0 = time.perf_counter()
    paths = synth(args.actuators, args.days, args.out, args.seed, _workers(args),
                  scheduler=args.scheduler, wear=args.wear)
    dt = time.perf_counter() - t0
    print(f"{len(paths)} logs in {args.out} ({dt:.1f} s, {len(paths) / dt:.2f} logs/s)")
    return 0
