"""`bench log FILE.log`: record every frame on the bus, like `candump -L`, through python-can's
`can.Logger` (the format from the suffix) or `can.SizedRotatingLogger` (`--max-bytes`)."""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from pathlib import Path

from bench import BenchError
from bench.cli import options as opt


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = opt.add_command(sub, "log", "record the bus to a log (candump -L by default)", """
        Record every frame on the bus (any bus python-can opens; by default the loopback hub of
        `bench up` or vcan0) to a log, until Ctrl-C, --duration or --count. The suffix picks the
        format, as python-can's can.Logger does: .log candump -L (default), .asc and .blf
        (Vector), .trc (PEAK), .mf4 (ASAM MDF4).""")
    p.add_argument("file", metavar="FILE.log", help="log to write (.log, .asc, .blf, .trc, "
                   ".mf4)")
    p.add_argument("--max-bytes", type=int, default=0, metavar="N",
                   help="start a new file when the current one reaches N bytes (python-can's "
                        "SizedRotatingLogger; .log, .asc, .blf): the full ones are renamed "
                        "FILE_<date>T<time>_#NNN.ext, FILE is always the newest (default: "
                        "one file)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after S seconds")
    p.add_argument("--count", type=int, default=None, metavar="N", help="stop after N frames")
    opt.add_bus(p)
    p.set_defaults(func=run)


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse, before touching the bus, what would never end or record nothing."""
    from bench.cli.outputs import check_output_file
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise BenchError(f"--duration must be a finite number of seconds > 0, not "
                         f"{args.duration:g} (without it: until Ctrl-C)")
    if args.count is not None and args.count < 1:
        raise BenchError(f"--count must be >= 1 frame, not {args.count}")
    if args.max_bytes < 0:
        raise BenchError(f"--max-bytes must be >= 0 (0: one file), not {args.max_bytes}")
    from bench.bus.logwrite import LOG_FORMATS, ROTATING_FORMATS
    check_output_file(args.file, "FILE.log", tuple(LOG_FORMATS))   # the format from it
    if args.max_bytes and Path(args.file).suffix.lower() not in ROTATING_FORMATS:
        raise BenchError(f"--max-bytes: python-can rotates {', '.join(ROTATING_FORMATS)} logs, "
                         f"not {Path(args.file).suffix.lower()}")


def run(args: argparse.Namespace) -> int:
    from bench.bus import bus_settings, close_bus, connect, find_bus
    from bench.bus.logwrite import flush, open_writer
    from bench.runtime import interrupts

    check_arguments(args)
    found = find_bus(bus_settings(args))
    if found is None:
        raise BenchError("no bus to record: no python-can configuration, no vcan0 and no "
                         "loopback hub running (run `bench up`)")
    cfg, source = found
    try:
        writer = open_writer(args.file, args.max_bytes)
    except OSError as exc:
        raise BenchError(f"cannot write {args.file}: {exc.strerror or exc}") from None
    try:
        bus = connect(cfg)
    except BaseException:
        writer.stop()
        raise
    stop = {"flag": False}

    def on_signal(signum, frame):  # noqa: ARG001
        stop["flag"] = True

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    stop["flag"] = interrupts.pending()     # a Ctrl-C lost in an import stops it now
    n = 0
    end = None if args.duration is None else time.monotonic() + args.duration
    print(f"recording {cfg.get('interface')}:{cfg.get('channel')} ({source}) to {args.file}",
          file=sys.stderr, flush=True)
    last_flush = time.monotonic()
    try:
        while not stop["flag"]:
            if end is not None and time.monotonic() >= end:
                break
            if args.count is not None and n >= args.count:
                break
            try:
                msg = bus.recv(0.1)
            except Exception as exc:  # noqa: BLE001 - a dead bus ends the recording
                raise BenchError(f"the bus failed after {n} frames: {exc}") from None
            if msg is None:
                continue
            writer.on_message_received(msg)
            n += 1
            now = time.monotonic()
            if now - last_flush > 0.5:
                flush(writer)
                last_flush = now
    finally:
        writer.stop()
        close_bus(bus)
        for s, h in old.items():
            signal.signal(s, h)
    print(f"{n} frames written to {args.file}")
    return 0
