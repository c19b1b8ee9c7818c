"""The options several commands share are defined once, in `bench.cli.options` (as
python-can's `can.cli.add_bus_arguments` is): no command defines `--workers` itself, and
every command's `--workers` has the one default or the literal one the module names."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

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


def test_a_node_id_outside_1_to_127_is_refused_before_any_bus(capsys):
    """`bench status --node-id 200` ended in "error: ValueError: CANopen node id must be
    1..127" (exit 1) and `bench up --node-id 200` started the plant first."""
    from bench.cli import main
    for argv in (["status", "--node-id", "200"], ["up", "--node-id", "0"],
                 ["run", "step", "--node-id", "0x80", "--duration", "0.2"]):
        with pytest.raises(SystemExit) as ex:
            main(argv)
        assert ex.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "a CANopen node id is 1 to 127" in err[0], err


def test_a_seed_outside_the_generators_range_is_one_line(capsys):
    """`--seed -1` ended in numpy's or scikit-learn's ValueError (exit 1)."""
    from bench.cli import main
    commands = (["fleet", "synth", "--actuators", "1", "--days", "1", "--out", "x"],
                ["hums", "campaign"], ["hums", "campaign", "--usage"],
                ["hums", "prognose", "--trends", "t.csv"], ["gap-bench"],
                ["rig", "train", "a.csv", "-o", "m.skops"])
    for cmd in commands:
        for seed in ("-1", str(2**32)):
            with pytest.raises(SystemExit) as ex:
                main([*cmd, "--seed", seed])
            assert ex.value.code == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and "a seed is 0 to 4294967295" in err[0], (cmd, err)


def test_a_plant_parameter_out_of_range_is_the_users_error(monkeypatch, capsys):
    """A ParameterError (a value the user gave, e.g. `--load-rating-n 1e308`) printed
    "error: ParameterError: ..." with exit 1, as for a fault of the bench."""
    import bench.cli as cli
    from plant_rt.params import ParameterError

    def refuse(args):
        raise ParameterError("screw.dynamic_load_rating_n = 1e+308 N is above its maximum")
    monkeypatch.setattr(cli, "_run", refuse)
    assert cli.main(["status"]) == 2
    assert capsys.readouterr().err == ("error: screw.dynamic_load_rating_n = 1e+308 N is above "
                                       "its maximum\n")
