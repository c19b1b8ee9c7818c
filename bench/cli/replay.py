"""`bench replay FILE.log`: play a bus log (candump, or .asc/.blf/.trc/.mf4) onto the bus,
like canplayer."""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import can

from bench import BenchError
from bench.cli import options as opt

MAX_GAP_S = 10.0


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = opt.add_command(sub, "replay", "play a bus log onto the bus (like canplayer)", """
        Send the frames of a bus log onto the bus with their original timing (relative to the
        first frame). The format comes from the suffix: candump .log (default), .asc, .blf,
        .trc, .mf4 (read through python-can), each also .gz/.xz/.bz2-compressed. Truncated
        or corrupted candump lines, and frames whose timestamp is not finite, are reported
        with their line (frame) numbers and skipped.""")
    p.add_argument("file", metavar="FILE.log", help="bus log to play (.log, .asc, .blf, "
                   ".trc, .mf4; also .gz/.xz/.bz2-compressed)")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="time scale: 2 plays twice as fast; 0 sends as fast as possible "
                        "(default: %(default)s)")
    p.add_argument("--skip-bad", action="store_true",
                   help="exit 0 even when the log has bad lines")
    p.add_argument("--max-gap", type=float, default=MAX_GAP_S, metavar="S",
                   help="longest wait between two frames, in wall seconds: a longer step "
                        "between timestamps (either way) is played at once and counted "
                        "(default: %(default)s)")
    opt.add_bus(p)
    p.set_defaults(func=run)


def check_arguments(args: argparse.Namespace) -> Path:
    """Refuse a speed or gap a replay could wait forever on; the log must exist."""
    if not (math.isfinite(args.speed) and args.speed >= 0):
        raise BenchError(f"--speed must be a finite number >= 0 (0: as fast as possible), "
                         f"not {args.speed:g}")
    if not (math.isfinite(args.max_gap) and args.max_gap > 0):
        raise BenchError(f"--max-gap must be a finite number of seconds > 0, not "
                         f"{args.max_gap:g}")
    from bench.bus.logwrite import log_format
    path = Path(args.file)
    log_format(path, "FILE", compressed=True)
    if not path.is_file():
        raise BenchError(f"no such log: {path}")
    return path


def frames(path: Path, issues: list) -> Iterator[can.Message]:
    """The frames of a log: a candump log as `bench.bus.logs.read_log` reads it, and also
    with lines whose timestamp is not finite (a timestamp of 400 digits reads as inf)
    reported in `issues` and skipped: no time to play them at exists; another format
    through `bench.bus.logread.read_frames`, with the same check."""
    from bench.bus.logread import DECOMPRESS_ERRORS, cannot_decompress, open_log_text
    from bench.bus.logs import LogIssue, parse_line, read_frames
    from bench.bus.logwrite import log_suffixes
    fmt, comp = log_suffixes(path)
    if fmt != ".log":
        for i, msg in enumerate(read_frames(path, issues), start=1):
            if math.isfinite(msg.timestamp):
                yield msg
            else:
                issues.append(LogIssue(i, "timestamp is not finite", f"frame {i}"))
        return
    lineno = 0
    with open_log_text(path) as fh:
        try:
            for lineno, line in enumerate(fh, start=1):
                if not line.strip():
                    continue
                try:
                    msg = parse_line(line)
                except ValueError as exc:
                    issues.append(LogIssue(lineno, str(exc), line.rstrip("\r\n")))
                    continue
                if not math.isfinite(msg.timestamp):
                    issues.append(LogIssue(lineno, "timestamp is not finite",
                                           line.rstrip("\r\n")))
                    continue
                yield msg
        except DECOMPRESS_ERRORS as exc:
            if not comp:
                raise
            raise BenchError(f"{path}: {cannot_decompress(comp, exc, lineno)}") from None


class Pacer:
    """When to send each frame: at its log time relative to the previous time origin,
    divided by `speed`. A step between two frames longer than `max_gap` s of wall time
    (either way: a corrupted timestamp, two logs joined) is a jump: that frame goes at
    once and becomes the new origin, so the rest keep their timing."""

    def __init__(self, speed: float, max_gap: float) -> None:
        self.speed, self.max_gap = speed, max_gap
        self.origin: tuple[float, float] | None = None    # (log time s, perf_counter s)
        self.last: float | None = None
        self.jumps = 0

    def due(self, ts: float) -> float:
        """perf_counter time at which the frame of log time `ts` (s) is due."""
        now = time.perf_counter()
        if self.last is not None and abs(ts - self.last) / self.speed > self.max_gap:
            self.jumps += 1
            self.origin = None
        self.last = ts
        if self.origin is None:
            self.origin = (ts, now)
        return self.origin[1] + (ts - self.origin[0]) / self.speed


def wait_until(due: float) -> None:
    """Sleep, then spin the last 0.2 ms, until perf_counter() >= `due`."""
    while True:
        left = due - time.perf_counter()
        if left <= 0:
            return
        time.sleep(min(left, 0.05) if left > 2e-4 else 0)


def run(args: argparse.Namespace) -> int:
    from bench.bus import bus_settings, close_bus, connect, find_bus
    from bench.bus.logs import report_issues

    path = check_arguments(args)
    found = find_bus(bus_settings(args))
    if found is None:
        raise BenchError("no bus to play onto: no python-can configuration, no vcan0 and no "
                         "loopback hub running (run `bench up`)")
    cfg, source = found
    issues: list = []
    bus = connect(cfg)
    n = 0
    pacer = Pacer(args.speed, args.max_gap) if args.speed > 0 else None
    try:
        for msg in frames(path, issues):
            if msg.is_error_frame:
                continue
            if pacer is not None:
                wait_until(pacer.due(msg.timestamp))
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
    notes = []
    if issues:
        notes.append(f"{len(issues)} bad line{'s' if len(issues) != 1 else ''} skipped")
    if pacer is not None and pacer.jumps:
        notes.append(f"{pacer.jumps} jump{'s' if pacer.jumps != 1 else ''} in time of more "
                     f"than {args.max_gap:g} s (either way) played without waiting")
    print(f"{n} frames played onto {cfg.get('interface')}:{cfg.get('channel')} ({source})"
          + "".join(f"; {x}" for x in notes))
    if n == 0:                          # a binary file, an empty one: nothing was a log
        raise BenchError(f"{args.file}: no frame to play"
                         + (f" ({len(issues)} bad lines)" if issues else ": the log is empty"))
    if issues and not args.skip_bad:
        print(f"error: {args.file}: {len(issues)} bad line{'s' if len(issues) != 1 else ''} "
              "skipped (--skip-bad plays the rest and exits 0)", file=sys.stderr)
        return 1
    return 0
