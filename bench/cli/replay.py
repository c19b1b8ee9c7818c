"""`bench replay FILE.log`: play a candump log onto the bus, like canplayer."""

from __future__ import annotations

import argparse
import sys
import time

from bench import BenchError


def add_subparser(sub: argparse._SubParsersAction) -> None:
    from bench.bus import add_bus_arguments
    p = sub.add_parser("replay", help="play a candump log onto the bus (like canplayer)",
                       description="Send the frames of a candump log onto the bus with their "
                       "original timing (relative to the first frame). Truncated or corrupted "
                       "lines are reported with their line numbers and skipped.")
    p.add_argument("file", metavar="FILE.log", help="candump log to play")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="time scale: 2 plays twice as fast; 0 sends as fast as possible "
                        "(default: %(default)s)")
    p.add_argument("--skip-bad", action="store_true",
                   help="exit 0 even when the log has bad lines")
    add_bus_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bench.bus import bus_settings, close_bus, connect, find_bus
    from bench.bus.logs import read_log, report_issues

    if args.speed < 0:
        raise BenchError("--speed must be >= 0")
    found = find_bus(bus_settings(args))
    if found is None:
        raise BenchError("no bus to play onto: no python-can configuration, no vcan0 and no "
                         "loopback hub running (run `bench up`)")
    cfg, source = found
    issues: list = []
    bus = connect(cfg)
    n = 0
    t0_log = t0_wall = None
    try:
        for msg in read_log(args.file, issues):
            if msg.is_error_frame:
                continue
            if args.speed > 0:
                if t0_log is None:
                    t0_log, t0_wall = msg.timestamp, time.perf_counter()
                due = t0_wall + (msg.timestamp - t0_log) / args.speed
                while True:
                    left = due - time.perf_counter()
                    if left <= 0:
                        break
                    time.sleep(min(left, 0.05) if left > 2e-4 else 0)
            msg.channel = None
            try:
                bus.send(msg)
            except Exception as exc:  # noqa: BLE001
                raise BenchError(f"the bus failed after {n} frames: {exc}") from None
            n += 1
    finally:
        close_bus(bus)
    for line in report_issues(issues):
        print(f"{args.file}: {line}", file=sys.stderr)
    print(f"{n} frames played onto {cfg.get('interface')}:{cfg.get('channel')} ({source})"
          + (f"; {len(issues)} bad lines skipped" if issues else ""))
    return 0 if not issues or args.skip_bad else 1
