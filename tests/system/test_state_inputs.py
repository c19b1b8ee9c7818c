"""Durations, counts and speeds that are not numbers a run can end on:
refused in one line by `bench plant`, `python -m plant_rt`, `bench log` and `bench replay`;
a log with non-finite or absurd timestamps does not make `bench replay` wait forever.
Each command has a time limit, so a hang fails the test instead of hanging it."""

from __future__ import annotations

import subprocess
import sys

import pytest
from bus_helpers import ROOT

VIRTUAL = ["-i", "virtual", "-c", "state-inputs"]   # a bus in the process: nothing else
LIMIT_S = 45.0


def run(*cmd: str, tmp_path) -> subprocess.CompletedProcess:
    env = {"BENCH_STATE_DIR": str(tmp_path / "state"), "PATH": "/usr/bin:/bin",
           "HOME": str(tmp_path), "PYTHONPATH": str(ROOT)}
    try:
        return subprocess.run(list(cmd), capture_output=True, text=True, timeout=LIMIT_S,
                              cwd=str(ROOT), env=env)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{' '.join(cmd[2:])} hung (still running after {LIMIT_S:.0f} s)")


def one_line_error(r: subprocess.CompletedProcess, start: str) -> None:
    err = r.stderr.strip()
    assert r.returncode == 2, (r.returncode, err)
    assert err.startswith(f"error: {start}"), err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err


DURATION = "--duration must be a finite number of seconds > 0"
PLANT = [sys.executable, "-m", "plant_rt"]
BENCH_PLANT = [sys.executable, "-m", "bench", "plant"]


@pytest.mark.parametrize("cmd", [PLANT, BENCH_PLANT], ids=["plant_rt", "bench-plant"])
@pytest.mark.parametrize("flags,message", [
    *((["--duration", v], DURATION) for v in ("nan", "inf", "-1", "0")),
    (["--spin-us", "-5"], "--spin-us must be within 0..1000 us"),
    (["--parent-pid", "0"], "--parent-pid must be a process id > 0"),
])
def test_plant_refuses_bad_numbers(tmp_path, cmd, flags, message):
    one_line_error(run(*cmd, *flags, *VIRTUAL, tmp_path=tmp_path), message)


@pytest.mark.parametrize("flags,message", [
    *((["--duration", v], DURATION) for v in ("nan", "inf", "-2")),
    (["--count", "0"], "--count must be >= 1 frame"),
    (["--count", "-3"], "--count must be >= 1 frame"),
])
def test_log_refuses_bad_numbers(tmp_path, flags, message):
    r = run(sys.executable, "-m", "bench", "log", str(tmp_path / "x.log"), *flags, *VIRTUAL,
            tmp_path=tmp_path)
    one_line_error(r, message)
    assert not (tmp_path / "x.log").exists()


def test_log_with_a_duration_ends(tmp_path):
    r = run(sys.executable, "-m", "bench", "log", str(tmp_path / "x.log"), "--duration", "0.3",
            *VIRTUAL, tmp_path=tmp_path)
    assert r.returncode == 0 and "0 frames written" in r.stdout, r.stderr


@pytest.mark.parametrize("speed", ["nan", "inf", "-inf", "-1"])
def test_replay_refuses_bad_speeds(tmp_path, speed):
    log = tmp_path / "a.log"
    log.write_text("(1.000000) vcan0 123#00\n")
    r = run(sys.executable, "-m", "bench", "replay", str(log), f"--speed={speed}", *VIRTUAL,
            tmp_path=tmp_path)
    one_line_error(r, "--speed must be a finite number >= 0")


def test_replay_skips_non_finite_timestamps(tmp_path):
    """A timestamp of 400 digits reads as inf: such lines are skipped and reported as bad
    lines, the rest is played with its timing."""
    log = tmp_path / "a.log"
    log.write_text("(1.000000) vcan0 123#00\n"
                   f"({'9' * 400}.0) vcan0 123#01\n"
                   "(1.010000) vcan0 123#02\n")
    r = run(sys.executable, "-m", "bench", "replay", str(log), *VIRTUAL, tmp_path=tmp_path)
    assert r.returncode == 1, r.stderr
    assert "line 2: timestamp is not finite" in r.stderr and "Traceback" not in r.stderr
    assert "2 frames played" in r.stdout and "1 bad line skipped" in r.stdout
    r = run(sys.executable, "-m", "bench", "replay", str(log), "--skip-bad", *VIRTUAL,
            tmp_path=tmp_path)
    assert r.returncode == 0


def test_replay_does_not_wait_out_absurd_time_jumps(tmp_path):
    """A corrupted, finite timestamp 30,000 years ahead (and back again): the frame is
    played at once and the jump counted, the timing of the rest is kept."""
    log = tmp_path / "a.log"
    log.write_text("(1700000000.000000) vcan0 123#00\n"
                   "(1700000000.010000) vcan0 123#01\n"
                   "(2700000000000.000000) vcan0 123#02\n"
                   "(1700000000.020000) vcan0 123#03\n"
                   "(1700000000.200000) vcan0 123#04\n")
    r = run(sys.executable, "-m", "bench", "replay", str(log), *VIRTUAL, tmp_path=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "5 frames played" in r.stdout
    assert "2 jumps in time of more than 10 s (either way) played without waiting" in r.stdout
