"""`bench plant`: the actuator as a CANopen node on the bus (same as `python -m plant_rt`)."""

from __future__ import annotations

import argparse

from bench import BenchError
from bench.cli import options as opt


def add_subparser(sub: argparse._SubParsersAction) -> None:
    from plant_rt.cli import add_arguments
    p = opt.add_command(sub, "plant", "run the actuator plant as a CANopen node on the bus", """
        The EMA actuator plant as a CANopen node (NMT, heartbeat, SYNC-driven TPDOs, RPDO
        command, SDO parameters, EMCY). The bus comes from the flags below, python-can's
        environment or config file, vcan0, or the loopback hub of `bench up`. Same as `python -m
        plant_rt`.""")
    add_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from plant_rt.cli import PlantError
    from plant_rt.cli import run as run_plant
    try:
        return run_plant(args)
    except PlantError as exc:
        raise BenchError(str(exc)) from None
