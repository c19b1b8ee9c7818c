"""`bench hums watch`: the HUMS live on the bus, a passive client (docs/hums.md, "Live
monitoring"): one verdict row per command period, the usage of every run, and what the
watch saw of the bus."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from bench import BenchError
from bench.runtime import interrupts


def run_watch(args: argparse.Namespace) -> int:
    import csv
    import signal
    import sys

    from bench.bus import bus_settings, close_bus, connect, find_bus
    from bench.hums.live import LiveHums, format_result, watch
    _check_watch_args(args)
    from bench.cli.options import set_params
    params = set_params(args)
    hums = LiveHums(args.period, params, args.node_id)   # fits the monitor gain first
    usage = _UsageOut(hums, args.usage)
    found = find_bus(bus_settings(args))
    if found is None:
        raise BenchError("no bus to listen to: no python-can configuration, no vcan0 and no "
                         "loopback hub running (run `bench up`)")
    cfg, source = found
    bus = connect(cfg)
    out = None
    writer = None

    def on_result(r) -> None:
        nonlocal writer
        print(format_result(r), flush=True)
        usage.update()
        if out is not None:
            row = r.row()
            if writer is None:
                writer = csv.DictWriter(out, fieldnames=list(row))
                if out.tell() == 0:             # a watch's earlier rows have theirs
                    writer.writeheader()
            writer.writerow(row)
            out.flush()

    def on_signal(signum, frame):  # noqa: ARG001
        raise KeyboardInterrupt

    old = {s_: signal.signal(s_, on_signal) for s_ in (signal.SIGINT, signal.SIGTERM)}
    n = 0
    try:
        if args.out:                    # new or empty (`_check_watch_outputs`): appended to
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            out = open(args.out, "a", newline="")  # noqa: SIM115 - closed in finally
        if interrupts.pending():        # a Ctrl-C lost in an import: stop before listening
            raise KeyboardInterrupt
        n = watch(bus, hums, on_result, args.duration, args.idle,
                  ready=lambda: print(f"listening on {cfg.get('interface')}:"
                                      f"{cfg.get('channel')} ({source}), command period "
                                      f"{args.period:g} s", file=sys.stderr, flush=True))
    except KeyboardInterrupt:
        pass
    finally:
        for s_, h in old.items():
            signal.signal(s_, h)
        close_bus(bus)
        if out is not None:
            out.close()
    usage.finish()
    _watch_summary(n, hums, args.out)
    return 0


class _UsageOut:
    """The watcher's usage (bench/usage): a table row per run when it ends, on stdout;
    with ``--usage FILE.json`` every run and actuator so far, rewritten per period."""

    def __init__(self, hums, path: str | None) -> None:
        self.hums, self.path, self.printed = hums, path, 0

    def update(self) -> None:
        from bench.usage.table import format_table
        done = self.hums.usage.done
        if len(done) > self.printed:
            print(format_table([(f"usage run {k + 1}", s)
                                for k, s in enumerate(done) if k >= self.printed]), flush=True)
            self.printed = len(done)
        if self.path:
            self._write()

    def _write(self) -> None:
        import os
        assert self.path is not None
        runs = self.hums.usage.runs()
        doc = {"runs": [s.to_json() for s in runs],
               "actuators": {k: s.to_json() for k, s in self.hums.usage.totals().items()}}
        tmp = Path(f"{self.path}.tmp")
        tmp.write_text(json.dumps(doc, indent=1))
        os.replace(tmp, self.path)

    def finish(self) -> None:
        self.hums.usage.end_run()
        self.update()


def _check_watch_args(args: argparse.Namespace) -> None:
    """The options and output files, before the monitor gain fit and the bus (an error
    once the bus is open would print a second line as it closes)."""
    for name in ("period", "idle"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise BenchError(f"--{name} must be > 0 s")
    if args.duration is not None and not args.duration > 0:
        raise BenchError("--duration must be > 0 s")
    _check_watch_outputs(args)


def _check_watch_outputs(args: argparse.Namespace) -> None:
    """--out (its directory made) and --usage (.json, its directory existing): writable,
    and new, empty or a watch's own (`_watch_wrote`): --out gets this watch's rows appended,
    --usage is rewritten every period, and either would destroy another file there (a
    log named by mistake)."""
    import os

    from bench.cli.outputs import check_output_file
    for flag, path, suffixes, parents in (("--out", args.out, None, True),
                                          ("--usage", args.usage, (".json",), False)):
        if not path:
            continue
        check_output_file(path, flag, suffixes, make_parents=parents)
        if os.path.isfile(path) and os.path.getsize(path) > 0 and not _watch_wrote(flag, path):
            raise BenchError(f"{flag} {path} exists and is not a watch's ("
                             f"{os.path.getsize(path)} bytes): name a new file for this "
                             "watch to write")


def _watch_wrote(flag: str, path: str) -> bool:
    """`path` is what a watch writes to `flag`: rows of the CSV (--out; this watch's are
    appended) or the usage JSON (--usage; rewritten). Another file there would be lost."""
    try:
        with open(path, encoding="utf-8") as fh:
            if flag == "--out":
                return fh.readline().startswith("run,period,t_start_s,")
            doc = json.load(fh)
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(doc, dict) and {"runs", "actuators"} <= set(doc)


def _watch_summary(n: int, hums, out: str | None) -> None:
    """What the watcher saw, on stderr: periods, runs, frames, and any damage on the bus."""
    import sys

    from bench.signals.integrity import integrity
    print(f"{n} command periods over {hums.run} run(s), {hums.frames_seen} frames"
          + (f", {hums.bad_frames} bad" if hums.bad_frames else "")
          + (f"; rows in {out}" if out else ""), file=sys.stderr)
    damage = integrity(hums.count)
    if damage:
        print("bus: " + "; ".join(damage), file=sys.stderr)
