"""The one `bench` entry point, one module per subcommand (as cantools' ``subparsers/``).

Each subcommand module defines ``add_subparser(subparsers)`` which registers its parser
and sets ``func`` (called with the parsed namespace, returns an exit code or None).
Modules are imported lazily by name so a broken optional dependency of one command does
not break the others.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from bench import BenchError, __version__

# subcommand name -> module under bench.cli
SUBCOMMANDS: dict[str, str] = {
    "demo": "demo",
    "reproduce": "reproduce",
    "plant": "plant",
    "up": "updown",
    "status": "updown",
    "down": "updown",
    "run": "run",
    "log": "logcmd",
    "replay": "replay",
    "decode": "decode",
    "hums": "hums",
    "gap": "gap",
    "gap-bench": "gapbench",
    "calibrate": "calibrate",
    "import": "importcmd",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bench",
        description="EMA ball-screw HUMS test bench: plant over CAN, ECU, HUMS, gap diagnosis.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")
    seen: set[str] = set()
    for module in SUBCOMMANDS.values():
        if module in seen:
            continue
        try:
            mod = importlib.import_module(f"bench.cli.{module}")
        except ModuleNotFoundError as exc:  # command not written yet, or missing dependency
            if exc.name and exc.name.startswith("bench.cli."):
                continue
            raise
        seen.add(module)
        mod.add_subparser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        rc = args.func(args)
    except BenchError as exc:
        if args.debug:
            traceback.print_exc()
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - the CLI never shows a bare traceback
        if args.debug:
            traceback.print_exc()
        print(f"error: {type(exc).__name__}: {exc} (run with --debug for a traceback)",
              file=sys.stderr)
        return 1
    return int(rc or 0)


if __name__ == "__main__":
    raise SystemExit(main())
