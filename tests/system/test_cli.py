"""Every `bench` command answers --help in a subprocess; errors are one line, no traceback."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from bench.cli import build_parser


def run_bench(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True,
                          text=True, timeout=timeout)


def commands() -> list[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sorted(sub.choices)


def test_top_level_help_lists_commands():
    r = run_bench("--help")
    assert r.returncode == 0
    for name in commands():
        assert name in r.stdout


@pytest.mark.parametrize("name", commands())
def test_every_command_has_help(name):
    r = run_bench(name, "--help")
    assert r.returncode == 0, r.stderr
    assert "usage:" in r.stdout


def test_python_m_plant_rt_help():
    r = subprocess.run([sys.executable, "-m", "plant_rt", "--help"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr


def test_bad_parameter_is_one_line_error(tmp_path):
    r = run_bench("reproduce", "--only", "P1-P3", "--set", "screw.nut_mass_kg=-1",
                  "--out", str(tmp_path / "r"), "--figures", "")
    assert r.returncode == 2
    assert r.stderr.strip() == ("error: screw.nut_mass_kg = -1 kg is below its minimum "
                                "0.001 kg")
    assert "Traceback" not in r.stderr


def test_reproduce_end_to_end(tmp_path):
    out, js, figs = tmp_path / "repro", tmp_path / "repro.json", tmp_path / "figs"
    r = run_bench("reproduce", "--only", "P1-P3", "--only", "P8", "--out", str(out),
                  "--json", str(js), "--figures", str(figs), timeout=300)
    assert r.returncode == 0, r.stderr
    rows = json.loads(js.read_text())
    assert {"id", "quantity", "unit", "thesis", "project"} <= set(rows[0])
    ids = {row["id"] for row in rows}
    assert ids == {"P1", "P2", "P3", "P8"}
    speed = next(r for r in rows if r["quantity"] == "motor speed at cruise")
    assert speed["thesis"] == 251.0 and abs(speed["project"] - 251.0) < 2.5
    text = (out / "reproduction.md").read_text()
    assert "| P8 | deflection ratio preloaded / unpreloaded |" in text
    assert (figs / "p1_step.png").stat().st_size > 10_000
