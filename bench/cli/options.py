"""The command-line options several `bench` commands share, each defined once, as
python-can's `can/cli.py` (`add_bus_arguments`) does for the bus flags: a command adds
them with `add_workers(parser)`, `add_out(parser, ...)`, `add_bus(parser)` ..., and
gives only what differs (its default, its help line) as arguments. A command itself is
added with `add_command(sub, name, help, description)`, its description a paragraph of
prose.

Worker processes (`--workers`): the one default is `None`, resolved where the work starts
(`bench.runtime.workers`, `bench.runtime.cluster.default_workers`): 2 local worker processes, or 1 on a
one-core machine, and 2 tasks at a time on a Dask scheduler. Two because the bench's
timings and its reference results come from a 2-core machine: one process per core, and
a local cluster never starts more processes than the cores this process may use. Two
commands keep the literal `DEFAULT_WORKERS` (2) as their default, since they record the
count in their results (`bench gap-bench --json` "workers") or test it (`bench gap`
fits in parallel above 1): the same 2 on the machines the default is meant for, without
moving a field. `bench hums prognose` keeps `None` with its own meaning (the trend's
prognosis in this process), said in its help.

Only argparse is imported here: light commands (`bench decode`) pay nothing for it.
"""

from __future__ import annotations

import argparse
from typing import Any

DEFAULT_WORKERS = 2
WORKERS_HELP = "worker processes (default: 2, or 1 on a one-core machine)"


def add_command(sub: argparse._SubParsersAction, name: str, help: str,  # noqa: A002
                description: str, **kwargs: Any) -> argparse.ArgumentParser:
    """A command (or sub-command) `name` under `sub`: its one-line `help` in its parent's
    list, and its `description` written as a paragraph of prose (a triple-quoted block),
    joined here into the one line argparse re-wraps to the terminal anyway."""
    return sub.add_parser(name, help=help, description=" ".join(description.split()),
                          **kwargs)


def add_workers(parser: argparse.ArgumentParser, default: int | None = None,
                help: str | None = None) -> None:  # noqa: A002 - argparse's own name
    """`--workers N` (see the module docstring for the default)."""
    if help is None:
        help = WORKERS_HELP if default is None else f"worker processes (default {default})"
    parser.add_argument("--workers", type=int, default=default, metavar="N", help=help)


def add_scheduler(parser: argparse.ArgumentParser, help: str | None = None) -> None:  # noqa: A002
    """`--scheduler ADDRESS`: an existing Dask cluster (`bench.runtime.cluster`)."""
    if help is None:
        from bench.runtime.cluster import SCHEDULER_HELP
        help = SCHEDULER_HELP
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None, help=help)


def add_out(parser: argparse.ArgumentParser, help: str | None = None, metavar: str = "DIR",
            default: str | None = None, required: bool = False,
            short: bool = False) -> None:
    """`--out` (with `-o` if `short`): where the command writes."""
    flags = ("-o", "--out") if short else ("--out",)
    parser.add_argument(*flags, metavar=metavar, default=default, required=required,
                        help=help)


def add_output(parser: argparse.ArgumentParser, help: str, metavar: str = "OUT",
               default: str | None = None) -> None:
    """`-o/--output`: the one file (or folder) a converting command writes."""
    parser.add_argument("-o", "--output", metavar=metavar, default=default, help=help)


def add_json(parser: argparse.ArgumentParser, help: str, metavar: str = "PATH") -> None:  # noqa: A002
    """`--json PATH`: the results as JSON too."""
    parser.add_argument("--json", metavar=metavar, help=help)


def add_effects(parser: argparse.ArgumentParser, also: str = "") -> None:
    """`--effects A,B,...`: the gap diagnosis' candidate effects (`bench gap --list-effects`)."""
    parser.add_argument("--effects", metavar="A,B,...",
                        help="candidate effects to try (default: the whole library; see "
                             f"`bench gap --list-effects`){also}")


def add_seed(parser: argparse.ArgumentParser, default: int, what: str = "random seed",
             metavar: str | None = None) -> None:
    """`--seed N`, its default said in the help."""
    parser.add_argument("--seed", type=seed_arg, default=default, metavar=metavar,
                        help=f"{what} (default {default})")


def add_set(parser: argparse.ArgumentParser, help: str, dest: str = "set") -> None:  # noqa: A002
    """`--set NAME=VALUE` (repeatable): parameter overrides."""
    parser.add_argument("--set", dest=dest, metavar="NAME=VALUE", action="append",
                        default=[], help=help)


def set_params(args: argparse.Namespace):
    """The nominal plant parameters with `--set NAME=VALUE` (`add_set`) applied; a bad one
    is a BenchError."""
    from bench import BenchError
    from plant_rt.params import ParameterError, PlantParams
    try:
        return PlantParams().with_assignments(args.set)
    except ParameterError as exc:
        raise BenchError(str(exc)) from None


def add_figures(parser: argparse.ArgumentParser, help: str, default: str | None = None  # noqa: A002
                ) -> None:
    """`--figures DIR`: PNG figures."""
    parser.add_argument("--figures", metavar="DIR", default=default, help=help)


def add_doc(parser: argparse.ArgumentParser, help: str) -> None:  # noqa: A002
    """`--doc PATH`: a markdown file whose generated section the command rewrites."""
    parser.add_argument("--doc", metavar="PATH", help=help)


def add_baseline(parser: argparse.ArgumentParser) -> None:
    """`--baseline BASE.json` and `--against`: judge a log against a healthy baseline, and
    with a calibration of another actuator (`--nominal`), whether its model or its
    baseline judges."""
    parser.add_argument("--baseline", metavar="BASE.json",
                        help="judge against this healthy baseline (`bench rig baseline`, or "
                             "the one `bench calibrate --actuator` wrote beside its "
                             "calibration)")
    parser.add_argument("--against", choices=("auto", "model", "baseline"), default="auto",
                        help="with a calibration of another actuator (--nominal): the model "
                             "when it reaches the noise floor on held-out healthy logs, else "
                             "the healthy baseline the calibration wrote (auto, default); or "
                             "force one")




SEED_RANGE = (0, 2**32 - 1)
"""A --seed: numpy's and scikit-learn's generators take 0 to 2**32 - 1."""


def seed_arg(text: str) -> int:
    """A --seed as given on the command line (decimal), in `SEED_RANGE`."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    lo, hi = SEED_RANGE
    if not lo <= v <= hi:
        raise argparse.ArgumentTypeError(f"{text}: a seed is {lo} to {hi}")
    return v


def add_node_id(parser: argparse.ArgumentParser) -> None:
    """`--node-id N`: the actuator's node id (default: the DBC's, 0x10)."""
    from plant_rt.cli import node_id_arg
    parser.add_argument("--node-id", type=node_id_arg, default=None,
                        help="actuator node id (default 0x10)")


def add_serial(parser: argparse.ArgumentParser, also: str = "") -> None:
    """`--serial N`: the actuator's serial number (identity object 0x1018 sub 4); `also`
    ends the help line."""
    from plant_rt.cli import SERIAL_HELP, serial_arg
    parser.add_argument("--serial", type=serial_arg, default=None, metavar="N",
                        help=SERIAL_HELP + also)


def add_bus(parser: argparse.ArgumentParser) -> None:
    """python-can's own bus flags (-i/-c/-b/--fd/--bus-kwargs ...): `can.cli`'s."""
    from bench.bus import add_bus_arguments
    add_bus_arguments(parser)


__all__ = ["DEFAULT_WORKERS", "WORKERS_HELP", "add_baseline", "add_bus", "add_command", "add_doc", "add_figures",
           "add_json", "add_node_id", "add_out", "add_output", "add_scheduler", "add_seed",
           "add_serial", "add_set", "add_workers", "seed_arg", "set_params"]
