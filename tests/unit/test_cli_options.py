"""The options several commands share are defined once, in `bench.cli.options` (as
python-can's `can.cli.add_bus_arguments` is): no command defines `--workers` itself, and
every command's `--workers` has the one default or the literal one the module names."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from bench.cli import build_parser, options

ROOT = Path(__file__).resolve().parents[2]
SHARED = ("--workers", "--scheduler", "--node-id", "--serial", "--seed", "--figures", "--doc")
DEFINED_HERE = re.compile(r"""add_argument\(\s*(?:["']-\w["']\s*,\s*)?["'](--[\w-]+)["']""")


def _definitions(under: str = "bench") -> dict[str, list[str]]:
    """Flag -> the modules under `under` (but options.py) calling add_argument with it."""
    out: dict[str, list[str]] = {}
    for path in sorted((ROOT / under).rglob("*.py")):
        if path == ROOT / "bench" / "cli" / "options.py":
            continue
        for flag in DEFINED_HERE.findall(path.read_text()):
            out.setdefault(flag, []).append(str(path.relative_to(ROOT)))
    return out


def test_shared_options_are_defined_only_in_options_py():
    found = _definitions()
    assert "--workers" not in found, found.get("--workers")
    found = _definitions("bench/cli")              # the commands' parsers
    repeated = {f: found[f] for f in SHARED if f in found}
    assert not repeated, repeated


def test_the_pattern_sees_a_definition():
    """The scan above would see a command defining the flags itself."""
    src = 'p.add_argument("--workers", type=int, default=2)\nq.add_argument("-o", "--out")'
    assert DEFINED_HERE.findall(src) == ["--workers", "--out"]


def _subparsers(parser: argparse.ArgumentParser, path: str = "bench"):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield f"{path} {name}", sub
                yield from _subparsers(sub, f"{path} {name}")


def test_every_workers_option_has_the_one_default_or_the_named_literal():
    seen = {}
    for name, sub in _subparsers(build_parser()):
        for action in sub._actions:
            if "--workers" in action.option_strings:
                seen[name] = action.default
                assert action.type is int and action.metavar == "N", name
                assert action.default in (None, options.DEFAULT_WORKERS), (name, action.default)
                if action.default is None and name != "bench hums prognose":
                    assert action.help == options.WORKERS_HELP, name
    # the commands that run work on workers all take the option
    assert {"bench gap", "bench gap-bench", "bench rig study", "bench fleet synth",
            "bench hums sweep", "bench hums prognose"} <= set(seen), sorted(seen)
    assert seen["bench gap"] == seen["bench gap-bench"] == options.DEFAULT_WORKERS == 2
    assert seen["bench rig study"] is None and seen["bench fleet synth"] is None


def test_debug_after_the_command_shows_the_traceback(tmp_path, capsys):
    """The one-line errors say "run with --debug"; `bench gap LOG --debug` was refused
    ("unrecognized arguments: --debug"): only `bench --debug gap LOG` worked."""
    from bench.cli import _debug_anywhere, main
    missing = str(tmp_path / "x.log")
    assert main(["gap", missing, "--debug"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and err.rstrip().splitlines()[-1] == f"error: no such file: {missing}"
    assert main(["gap", missing]) == 2
    assert "Traceback" not in capsys.readouterr().err
    # after `--` it is an argument, not the flag
    assert _debug_anywhere(["gap", "--", "--debug"]) == (["gap", "--", "--debug"], False)
    assert _debug_anywhere(["--debug", "gap", "a"]) == (["--debug", "gap", "a"], False)
