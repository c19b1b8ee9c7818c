"""Command line of the plant node (`python -m plant_rt`, also `bench plant`).

    python -m plant_rt [--pace realtime|sync] [--set NAME=VALUE ...] [--serial N]
                       [-i IFACE -c CHANNEL]
    python -m plant_rt --list-params

The bus comes from python-can's flags, environment or config file, else vcan0, else a
loopback hub started by `bench up` (see `ema_contract.transport`).
"""

from __future__ import annotations

import argparse
import gc
import logging
import math
import os
import signal
import sys
import tempfile
from pathlib import Path
from typing import Any

import can.cli

from ema_contract.states import Pace
from ema_contract.transport import (
    BusUnavailable,
    close_bus,
    describe,
    open_bus,
    pid_alive,
    resolve,
)
from plant_rt.pacing import use_realtime_priority
from plant_rt.params import PARAMS, ParameterError, PlantParams

BUS_KEYS = ("interface", "channel", "bitrate", "fd", "data_bitrate", "timing")


class PlantError(Exception):
    """A user error of the plant command (printed as one line)."""


SERIAL_HELP = ("the actuator's serial number, identity object 0x1018 sub 4 (UNSIGNED32, "
               "decimal or 0x hex; default: the EDS's, 0)")


def _int_arg(text: str, what: str) -> int:
    """An argparse type's integer, decimal or 0x hex (`what` names it in the error)."""
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None


def serial_arg(text: str) -> int:
    """An argparse type: a serial number (UNSIGNED32, decimal or 0x hex)."""
    value = _int_arg(text, "an integer")
    if not 0 <= value <= 0xFFFFFFFF:
        raise argparse.ArgumentTypeError(f"{value} is not within 0..4294967295 (UNSIGNED32)")
    return value


def node_id_arg(text: str) -> int:
    """An argparse type: a CANopen node id (0x10, 16): 1 to 127 (CiA 301)."""
    value = _int_arg(text, "a node id")
    if not 1 <= value <= 127:
        raise argparse.ArgumentTypeError(f"{text}: a CANopen node id is 1 to 127 (0x01-0x7F)")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pace", choices=[p.name.lower() for p in Pace], default="realtime",
                        help="realtime: wall-clock periods with absolute deadlines; sync: one "
                             "period per SYNC frame (lockstep, deterministic) "
                             "(default: %(default)s)")
    parser.add_argument("--set", dest="assignments", action="append", default=[],
                        metavar="NAME=VALUE", help="set a plant parameter at start "
                        "(repeatable; see --list-params)")
    parser.add_argument("--params", metavar="FILE.json",
                        help="start from a parameter set saved as JSON")
    parser.add_argument("--list-params", action="store_true",
                        help="print every settable parameter with unit, default and range")
    parser.add_argument("--node-id", type=node_id_arg, default=None,
                        help="CANopen node id (default 0x10, from dbc/ema.dbc)")
    parser.add_argument("--ecu-id", type=node_id_arg, default=None,
                        help="node id of the ECU whose heartbeat is consumed (default 0x01)")
    parser.add_argument("--serial", type=serial_arg, default=None, metavar="N",
                        help=SERIAL_HELP)
    parser.add_argument("--spin-us", type=int, default=200,
                        help="real-time pacer: busy-wait window before each period "
                             "(default: %(default)s us)")
    parser.add_argument("--rt-priority", type=int, default=0, metavar="N",
                        help="run under SCHED_FIFO at priority N (1-99; needs root or "
                             "CAP_SYS_NICE); 0: normal scheduling (default)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="exit after S seconds of wall time (default: run until stopped)")
    parser.add_argument("--ready-file", metavar="PATH",
                        help="touch PATH once the node has booted (for launchers)")
    parser.add_argument("--parent-pid", type=int, default=None, metavar="PID",
                        help="exit when process PID exits (for launchers)")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="log NMT changes and SDO refusals (-vv: debug)")
    can.cli.add_bus_arguments(parser)


def bus_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The python-can settings given on the command line (only those given)."""
    cfg: dict[str, Any] = {k: getattr(args, k) for k in BUS_KEYS if k in args}
    cfg.update(getattr(args, "bus_kwargs", None) or {})
    return cfg


def list_params(out=sys.stdout) -> None:
    """Every settable parameter: name, unit, default, range, description."""
    rows = []
    for p in PARAMS:
        if p.choices:
            rng = "|".join(p.choices)
        elif p.type is bool:
            rng = "on|off"
        else:
            lo = "-inf" if p.min is None else f"{p.min:g}"
            hi = "inf" if p.max is None else f"{p.max:g}"
            rng = f"[{lo}, {hi}]"
        d = p.default
        dflt = ("nan" if isinstance(d, float) and math.isnan(d) else
                ("on" if d else "off") if isinstance(d, bool) else f"{d:g}"
                if isinstance(d, (int, float)) else str(d))
        rows.append((p.name, p.unit, dflt, rng, p.doc))
    w = [max(len(r[i]) for r in rows) for i in range(4)]
    head = ("parameter", "unit", "default", "range")
    print("  ".join(h.ljust(w[i]) for i, h in enumerate(head)) + "  description", file=out)
    for r in rows:
        print("  ".join(r[i].ljust(w[i]) for i in range(4)) + "  " + r[4], file=out)


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse numbers the node cannot run with (NaN/inf durations never end)."""
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise PlantError(f"--duration must be a finite number of seconds > 0, not "
                         f"{args.duration:g} (without it: until stopped)")
    if not 0 <= args.spin_us <= 1000:
        raise PlantError("--spin-us must be within 0..1000 us")
    if not 0 <= args.rt_priority <= 99:
        raise PlantError("--rt-priority must be within 0..99")
    if args.parent_pid is not None and args.parent_pid <= 0:
        raise PlantError(f"--parent-pid must be a process id > 0, not {args.parent_pid}")
    if args.ready_file:
        check_ready_file(Path(args.ready_file))


READY = "ready\n"
"""What the node writes to --ready-file once it has booted."""


def check_ready_file(path: Path) -> None:
    """--ready-file as a file the node may write before it starts: in a folder that
    exists, and not a file of other content (a log named by mistake would be replaced)."""
    if path.is_dir():
        raise PlantError(f"--ready-file {path}: it is a directory")
    if not path.parent.is_dir():
        raise PlantError(f"--ready-file {path}: directory {path.parent} does not exist")
    try:                      # tried, not asked (os.access says yes to root on /proc)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=".ready-probe-"):
            pass
    except OSError:
        raise PlantError(f"--ready-file {path}: directory {path.parent} is not writable"
                         ) from None
    if path.exists() and path.stat().st_size and (
            path.stat().st_size > len(READY) or path.read_bytes() != READY.encode()):
        raise PlantError(f"--ready-file {path}: the file exists and is not a ready file "
                         f"({path.stat().st_size} bytes): name a new file")


def build_params(args: argparse.Namespace) -> PlantParams:
    try:
        params = PlantParams()
        if args.params:
            path = Path(args.params)
            if not path.exists():
                raise PlantError(f"no such parameter file: {path}")
            try:
                text = path.read_text()
            except (OSError, UnicodeDecodeError) as exc:
                raise PlantError(f"--params {path}: not a parameter file ({exc})") from None
            params = PlantParams.from_json(text)
        return params.with_assignments(args.assignments)
    except ParameterError as exc:
        raise PlantError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    """Start the node; returns when stopped (SIGINT/SIGTERM) or after --duration."""
    if args.list_params:
        try:
            list_params()
        except BrokenPipeError:  # `| head`: silence the flush at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    level = logging.WARNING if args.verbose == 0 else (
        logging.INFO if args.verbose == 1 else logging.DEBUG)
    logging.basicConfig(level=level, format="plant: %(message)s")
    check_arguments(args)
    params = build_params(args)
    try:
        found = resolve(bus_settings(args))
    except BusUnavailable as exc:
        raise PlantError(str(exc)) from None
    if found is None:
        raise PlantError("no CAN bus: no python-can configuration (-i/-c, CAN_INTERFACE, "
                         "~/.canrc), no vcan0, and no loopback hub running (start one with "
                         "`bench up`)")
    cfg, source = found
    from plant_rt.model import warm_up
    warm_up(params)             # before the bus opens: no frames queue while it loads
    from ema_contract.frames import Frames, exclude_filters
    from plant_rt.node import PlantNode
    try:
        frames = Frames(args.node_id, args.ecu_id)
    except ValueError as exc:
        raise PlantError(str(exc)) from None
    # the ECU's set-point frame (one per period) is for loggers, not for the actuator
    filters = exclude_filters([frames.cob["ECU_Setpoint"]])
    try:
        bus = open_bus(cfg, receive_own_messages=False, can_filters=filters)
    except BusUnavailable as exc:
        raise PlantError(str(exc)) from None
    try:
        node = PlantNode(bus, params, pace=Pace[args.pace.upper()], node_id=args.node_id,
                         ecu_id=args.ecu_id, spin_us=args.spin_us,
                         serial=getattr(args, "serial", None))
    except ValueError as exc:
        close_bus(bus)
        raise PlantError(str(exc)) from None

    def on_signal(signum, frame):  # noqa: ARG001
        node.stop()

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    # Everything allocated so far (numpy, numba, canopen, cantools: ~10^6 objects) is
    # permanent: freezing it keeps the cyclic GC from scanning it, which otherwise
    # stalls the loop for 30-70 ms at every full collection.
    gc.collect()
    gc.freeze()
    sched = use_realtime_priority(args.rt_priority)
    print(f"plant: node 0x{node.node_id:02X} on {describe(cfg)} ({source}), "
          f"pace {args.pace}, {sched}", file=sys.stderr, flush=True)
    try:
        if args.ready_file:
            Path(args.ready_file).write_text(READY)
        parent = args.parent_pid
        node.run(args.duration, alive=(lambda: pid_alive(parent)) if parent else None)
    except ConnectionError as exc:
        raise PlantError(f"{exc}") from None
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        close_bus(bus)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m plant_rt",
        description="The EMA actuator plant as a CANopen node on a CAN bus.")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except PlantError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # noqa: BLE001 - never a bare traceback to the user
        if args.debug:
            raise
        print(f"error: {type(exc).__name__}: {exc} (run with --debug for a traceback)",
              file=sys.stderr)
        return 1
