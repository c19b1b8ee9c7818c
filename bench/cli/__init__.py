"""The one `bench` entry point, one module per subcommand (as cantools' ``subparsers/``).

Each subcommand module defines ``add_subparser(subparsers)`` which registers its parser
and sets ``func`` (called with the parsed namespace, returns an exit code or None).
Only the module of the command being run is imported: the others appear in
``bench --help`` from the table below (name, module, one-line help), so `bench --help`
and light commands such as `bench decode` do not pay for the heavy ones' imports (numba,
scipy, matplotlib), and a broken optional dependency of one command does not break the
others. A unit test checks the table's help lines against the modules' parsers.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
from typing import NoReturn

from bench import BenchError, __version__, refuse_mf4_import

# subcommand name -> (module under bench.cli, the help line its parser registers)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("demo", "the main job on embedded defaults: healthy, worn and failing actuator "
                     "over the bus, HUMS report, gap diagnosis"),
    "reproduce": ("reproduce", "reproduce thesis chapter 5 (P1-P9) side by side"),
    "plant": ("plant", "run the actuator plant as a CANopen node on the bus"),
    "up": ("updown", "start the loopback bus and the plant in the background"),
    "status": ("updown", "show the plant node's state, counters and parameters"),
    "down": ("updown", "stop the background plant and loopback bus"),
    "run": ("run", "run a profile against the plant over the CAN bus (the ECU)"),
    "log": ("log", "record the bus to a log (candump -L by default)"),
    "replay": ("replay", "play a bus log onto the bus (like canplayer)"),
    "decode": ("decode", "decode a bus log into a signal table (CSV/Parquet)"),
    "hums": ("hums", "health and usage monitoring (thesis chapter 6)"),
    "usage": ("usage", "usage monitoring: travel, reversals, cycles, load spectrum, life used"),
    "gap": ("gap", "diagnose the gap between a log and the nominal model"),
    "gap-bench": ("gap_bench", "blind check of the gap diagnosis on generated logs"),
    "calibrate": ("calibrate", "fit the nominal model to a healthy log"),
    "import": ("importcmd", "import a CSV/Parquet table from another rig"),
    "fleet": ("fleet", "fleet store: ingest logs, status, report, export, synthetic fleet"),
    "rig": ("rig", "baselines, fault signatures and populations of a real rig's runs"),
}


# a `bench` command run as its own process refuses python-can's MF4 import until it opens
# an MF4 log (`bench.refuse_mf4_import`, `bench.allow_mf4_import`; 0.6-2 s of CPU of every
# command's start-up); never for `main(argv)` in-process


def selected_command(argv: list[str]) -> str | None:
    """The subcommand `argv` runs: its first word that is not an option (the top-level
    options take no value), None if there is none."""
    for i, arg in enumerate(argv):
        if arg == "--":
            return argv[i + 1] if i + 1 < len(argv) else None
        if not arg.startswith("-"):
            return arg
    return None


class OneLineParser(argparse.ArgumentParser):
    """argparse's parser whose usage errors are one line, as every error of the bench
    (``error: bench decode: argument --period: invalid float value: 'x' (see bench decode
    --help)``, exit 2), instead of the usage text and then the error."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"error: {self.prog}: {' '.join(message.split())} (see {self.prog} "
                     "--help)\n")


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The `bench` parser: the full parser of the command `argv` selects (its module
    imported), a help-only entry for every other command (nothing imported).
    `argv=None` means every module (what `bench --help` lists, fully built: tests)."""
    parser = OneLineParser(
        prog="bench",
        description="EMA ball-screw HUMS test bench: plant over CAN, ECU, HUMS, gap diagnosis.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")
    command = None if argv is None else selected_command(argv)
    chosen = SUBCOMMANDS[command][0] if command in SUBCOMMANDS else None
    for name, (module, help_line) in SUBCOMMANDS.items():
        if name in sub.choices:          # registered with another command of its module
            continue
        if argv is None or module == chosen:
            importlib.import_module(f"bench.cli.{module}").add_subparser(sub)
        else:
            sub.add_parser(name, help=help_line, add_help=False)
    return parser


def _debug_anywhere(argv: list[str]) -> tuple[list[str], bool]:
    """`argv` without a `--debug` given after the command (`bench gap LOG --debug`, as the
    one-line errors suggest), and whether there was one: the flag is the top-level
    parser's, which sees only what stands before the command."""
    cmd = selected_command(argv)
    if cmd is None:
        return argv, False
    start = argv.index(cmd) + 1
    end = argv.index("--", start) if "--" in argv[start:] else len(argv)
    rest = [a for a in argv[start:end] if a != "--debug"]
    return argv[:start] + rest + argv[end:], len(rest) < end - start


def main(argv: list[str] | None = None) -> int:
    from bench.runtime import interrupts
    with interrupts.counting():     # a Ctrl-C that an import swallows is still seen
        rc = _main(argv)
    try:
        sys.stdout.flush()          # what is still buffered, while a closed pipe is caught
    except BrokenPipeError:
        return _reader_gone()
    return rc


def _main(argv: list[str] | None) -> int:
    if argv is None:
        refuse_mf4_import()
    argv = sys.argv[1:] if argv is None else list(argv)
    argv, debug = _debug_anywhere(argv)
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    args.debug = args.debug or debug
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from bench.core.filenames import one_line
    from plant_rt.params import ParameterError
    try:
        rc = _run(args)
    except (BenchError, ParameterError) as exc:   # the user's input (a plant parameter too)
        if args.debug:
            traceback.print_exc()
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return _reader_gone()
    except OSError as exc:
        if args.debug:
            traceback.print_exc()
        if exc.filename is None:
            print(f"error: {type(exc).__name__}: {one_line(str(exc))} (run with --debug for "
                  "a traceback)", file=sys.stderr)
            return 1
        # a file the user named that the system refuses (name too long, not a directory)
        print(f"error: {one_line(str(exc.filename))}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the CLI never shows a bare traceback
        if args.debug:
            traceback.print_exc()
        print(f"error: {type(exc).__name__}: {one_line(str(exc))} (run with --debug for a "
              "traceback)", file=sys.stderr)
        return 1
    return int(rc or 0)


def _run(args: argparse.Namespace) -> int | None:
    """The command, once its outputs are checked against its inputs (none is one of them,
    `bench.cli.outputs.check_io`) and with its inputs guarded while it runs
    (`bench.core.filenames.protect`: a file named from data that would be one is refused)."""
    from bench.cli.outputs import check_io, inputs
    from bench.core.filenames import protect
    check_io(args)
    with protect(inputs(args)):
        return args.func(args)


def _reader_gone() -> int:
    """The reader of stdout went away (`bench status | head -3`): end quietly, as a Unix
    tool killed by SIGPIPE would (exit 141), and point stdout at /dev/null so that the
    interpreter's final flush does not raise again (Python's documented recipe)."""
    import os
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 141


if __name__ == "__main__":
    raise SystemExit(main())
