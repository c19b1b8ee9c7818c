"""The three layers and their arrows: `ema_contract` (the bus contract) imports neither
`plant_rt` nor `bench` nor numba; `plant_rt` never imports `bench`; `bench decode` and
`bench --help` run without numba or the compiled kernel (the subcommands are imported
lazily), and the help table of `bench.cli` says what the modules register."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import can

from bench.cli import SUBCOMMANDS, build_parser, selected_command
from ema_contract.frames import Frames

ROOT = Path(__file__).resolve().parents[2]


def _imported_roots(package: str) -> dict[str, set[str]]:
    """Top-level package names each module of `package` imports (anywhere in it)."""
    out: dict[str, set[str]] = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        roots: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                roots |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                roots.add(node.module.split(".")[0])
        out[str(path.relative_to(ROOT))] = roots
    return out


def test_arrows_point_one_way():
    for module, roots in _imported_roots("ema_contract").items():
        assert not roots & {"plant_rt", "bench", "numba", "scipy"}, (module, roots)
    for module, roots in _imported_roots("plant_rt").items():
        assert "bench" not in roots, module


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=str(ROOT))


def test_contract_and_parameters_load_without_numba():
    r = _python(
        "import sys\n"
        "from ema_contract.frames import Frames, load_od\n"
        "from ema_contract import states, transport\n"
        "import plant_rt.params, plant_rt.paramobjects\n"
        "Frames(); plant_rt.paramobjects.ParamObjects(load_od())\n"
        "heavy = sorted(m for m in ('numba', 'plant_rt.kernel', 'plant_rt.model', 'bench')\n"
        "               if m in sys.modules)\n"
        "assert not heavy, heavy\n")
    assert r.returncode == 0, r.stderr


def _write_log(path: Path, periods: int = 40) -> None:
    """A candump log of `periods` SYNC periods: SYNC, the ECU's RPDO1, the plant's TPDOs."""
    f = Frames()
    writer = can.CanutilsLogWriter(str(path), channel="vcan0")
    t = 1000.0
    for k in range(periods):
        x = 1e-4 * k
        frames = [
            ("SYNC", {"SYNC_Counter": k % 240 + 1}),
            ("EMA_TPDO1", {"MotorCurrent": 0.5 + 0.01 * k, "StatusWord": 0x40}),
            ("EMA_TPDO2", {"EncoderAngle": 100 * k, "EncoderSpeed": 1.5}),
            ("EMA_TPDO3", {"LvdtPosition": x, "WindingTemperature": 300.0, "LoadForce": 2}),
            ("ECU_Setpoint", {"SetpointPosition": x, "SetpointSpeed": 0.0, "Mode": 1}),
            ("EMA_RPDO1", {"CurrentDemand": 0.5, "ControlWord": 1}),
        ]
        for i, (name, values) in enumerate(frames):
            msg = f.encode(name, values)
            msg.timestamp = t + 1e-3 * k + 1e-5 * i
            writer.on_message_received(msg)
    writer.stop()


def test_bench_decode_imports_neither_numba_nor_the_kernel(tmp_path):
    log = tmp_path / "small.log"
    _write_log(log)
    r = _python(
        "import sys, bench.cli\n"
        f"rc = bench.cli.main(['decode', {str(log)!r}, '-o', {str(tmp_path / 't.csv')!r}])\n"
        "assert rc == 0, rc\n"
        "heavy = sorted(m for m in ('numba', 'plant_rt.kernel', 'plant_rt.model', 'scipy',\n"
        "                           'matplotlib') if m in sys.modules)\n"
        "assert not heavy, heavy\n")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "40 SYNC periods" in r.stdout, r.stdout
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 41


def test_bench_help_imports_no_subcommand():
    r = _python("import sys, bench.cli\n"
                "try:\n    bench.cli.main(['--help'])\nexcept SystemExit as e:\n"
                "    assert e.code == 0\n"
                "loaded = sorted(m for m in sys.modules if m.startswith('bench.cli.')\n"
                "                or m in ('numba', 'plant_rt', 'can', 'scipy'))\n"
                "assert not loaded, loaded\n")
    assert r.returncode == 0, r.stdout + r.stderr
    for name in SUBCOMMANDS:
        assert name in r.stdout


def test_help_table_matches_the_modules():
    parser = build_parser()          # every module imported, as the help entries come
    sub = next(a for a in parser._actions if a.dest == "command")
    registered = {a.dest: a.help for a in sub._choices_actions}
    assert registered == {name: help_line for name, (_, help_line) in SUBCOMMANDS.items()}
    assert list(sub.choices) == list(SUBCOMMANDS)


def test_selected_command():
    assert selected_command(["--debug", "decode", "x.log"]) == "decode"
    assert selected_command(["--help"]) is None
    assert selected_command(["--", "status"]) == "status"
    assert selected_command([]) is None


def test_the_ecu_loads_without_scipy_signal():
    """`bench run` starts an ECU process; scipy.signal (and the scipy.stats it pulls in) cost
    it ~0.5 s of start-up for the flight profile's turbulence filter alone, so that import
    waits until a turbulence is drawn."""
    r = _python("import sys, bench.ecu.master, bench.profiles.catalog, bench.profiles.flight\n"
                "assert 'scipy.signal' not in sys.modules\n"
                "import numpy as np\n"
                "y = bench.profiles.flight._turbulence(3000, 1e-4, np.random.default_rng(0))\n"
                "assert 'scipy.signal' in sys.modules and abs(float(np.std(y)) - 1e-4) < 1e-9\n")
    assert r.returncode == 0, r.stdout + r.stderr
