"""`python -m indie_plant --bus ...`: the independent actuator as a CANopen node.

    python -m indie_plant -i remote -c ws://127.0.0.1:PORT/ [--set NAME=VALUE ...]
                          [--load-n N --load-hz F] [--seed S] [--list-params]

Bus flags are python-can's (`-i/-c/-b`); without them the bus is chosen as the bench's
(`ema_contract.transport`: vcan0 where it exists, else the loopback hub of `bench up`).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import can
import can.cli


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m indie_plant",
                                description=__doc__.splitlines()[0])
    can.cli.add_bus_arguments(p)
    p.add_argument("--node-id", type=lambda s: int(s, 0), default=None)
    p.add_argument("--set", dest="assignments", action="append", default=[],
                   metavar="NAME=VALUE", help="actuator parameter (--list-params)")
    p.add_argument("--load-n", type=float, default=0.0, help="rig load sine amplitude (N)")
    p.add_argument("--load-hz", type=float, default=0.37, help="rig load frequency (Hz)")
    p.add_argument("--seed", type=int, default=1, help="sensor noise seed")
    p.add_argument("--list-params", action="store_true", help="list the parameters and exit")
    p.add_argument("--ready-file", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--parent-pid", type=int, help=argparse.SUPPRESS)
    p.add_argument("--duration", type=float, help="serve this long (s), then exit")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from indie_plant.params import IndieParams, table
    if args.list_params:
        for name, unit, value, why in table():
            print(f"{name:28s} {unit:10s} {value:<12.6g} {why}")
        return 0
    try:
        params = IndieParams().with_assignments(args.assignments)
        if not (math.isfinite(args.load_n) and math.isfinite(args.load_hz)
                and 0.0 <= args.load_hz <= 100.0):
            raise ValueError("--load-n must be finite and --load-hz in [0, 100]")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from ema_contract.drive import serve_process
    from ema_contract.frames import Frames, exclude_filters
    from ema_contract.transport import open_bus
    from indie_plant.generate import Actuator
    from indie_plant.node import IndieNode
    act = Actuator(params, args.seed)
    act.step(0.0)                       # compile before going on the bus
    act.reset()
    cfg = {"interface": args.interface, "channel": args.channel}
    setpoint = Frames(args.node_id).cob["ECU_Setpoint"]
    try:
        bus = open_bus(cfg, receive_own_messages=False, can_filters=exclude_filters([setpoint]))
    except Exception as exc:  # noqa: BLE001 - one line, not a traceback
        print(f"error: cannot open the bus: {exc}", file=sys.stderr)
        return 1
    node = IndieNode(bus, act, args.node_id, args.load_n, args.load_hz)
    serve_process(node, args.ready_file, args.parent_pid, args.duration)
    return 0


if __name__ == "__main__":
    sys.exit(main())
