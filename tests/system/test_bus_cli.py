"""The operator commands of the bus: up/status/down, run without `bench up`, plant, help."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from bus_helpers import ROOT, bench

from plant_rt.params import PARAMS


@pytest.fixture
def state_env(tmp_path):
    env = {**os.environ, "BENCH_STATE_DIR": str(tmp_path / "state")}
    for k in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_CONFIG"):
        env.pop(k, None)
    yield env
    bench("down", env=env, timeout=30)


def test_status_without_a_bench_is_a_one_line_error(state_env):
    t0 = time.monotonic()
    r = bench("status", env=state_env, timeout=30)
    assert r.returncode == 2
    assert r.stderr.strip().startswith("error: bench is not up")
    assert len(r.stderr.strip().splitlines()) == 1
    assert time.monotonic() - t0 < 10


def test_up_status_run_down(state_env, tmp_path):
    r = bench("up", "--pace", "sync", "--set", "effects.preload_n=1500", env=state_env,
              timeout=120)
    assert r.returncode == 0, r.stderr
    assert "hub: pid" in r.stdout and "plant: pid" in r.stdout and "127.0.0.1" in r.stdout
    assert "waiting for its boot-up" in r.stderr      # what `bench up` waits for
    r = bench("up", env=state_env)
    assert "already up" in r.stdout
    r = bench("status", env=state_env)
    assert r.returncode == 0, r.stderr
    assert "node 0x10: PRE_OPERATIONAL, pace sync" in r.stdout
    assert "effects.preload_n = 1500" in r.stdout
    assert "frames_received" in r.stdout
    r = bench("run", "velocity-step", "--pace", "sync", "--set", "effects.backlash_m=1e-5",
              env=state_env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "300 periods" in r.stdout and "(loopback hub of the bench in " in r.stdout
    r = bench("status", "--all", env=state_env)
    assert "effects.backlash_m = 1e-05" in r.stdout and "effects.preload_n = 1500" in r.stdout
    assert f"{len(PARAMS)}" and r.stdout.count(" = ") == len(PARAMS)
    r = bench("down", env=state_env)
    assert "stopped plant" in r.stdout and "stopped hub" in r.stdout
    r = bench("status", env=state_env)
    assert r.returncode == 2


def test_status_with_a_bus_but_no_plant_answers_within_two_seconds(state_env):
    hub = subprocess.Popen([sys.executable, "-m", "bench.bus.hub"], env=state_env,
                           stdout=subprocess.PIPE, text=True, cwd=str(ROOT))
    try:
        assert hub.stdout.readline().startswith("ws://127.0.0.1:")
        t0 = time.monotonic()
        r = bench("status", env=state_env, timeout=30)
        wall = time.monotonic() - t0
    finally:
        hub.terminate()
        hub.wait(10)
        hub.stdout.close()
    assert r.returncode == 2
    assert "no actuator node 0x10 answering" in r.stderr
    # the answer itself takes 0.35 s of heartbeat wait + 0.25 s of SDO timeout; the rest is
    # interpreter and import start-up of `bench`, which a loaded machine stretches (8.8 s
    # at a load average of 8 on 2 cores): the bound scales with the load per core, so it
    # still catches a wait for a long timeout on a quiet machine
    per_core = os.getloadavg()[0] / (os.cpu_count() or 1)
    assert wall < 6.0 * max(1.0, per_core), (wall, per_core)


def test_run_without_bench_up_starts_and_stops_its_own_bus_and_plant(state_env, tmp_path):
    r = bench("run", "step", "--pace", "sync", "--duration", "0.1", "--amplitude-m", "0.002",
              env=state_env, timeout=180)
    assert r.returncode == 0, r.stderr
    assert "private loopback hub" in r.stdout and "100 periods" in r.stdout
    assert "set-point 2.000 mm" in r.stdout
    r = bench("status", env=state_env)
    assert r.returncode == 2                      # nothing left running


@pytest.mark.parametrize("args, message", [
    (("run", "step", "--set", "motor.resistance_ohm=-1"),
     "error: motor.resistance_ohm = -1 ohm is below its minimum 0.0001 ohm"),
    (("run", "step", "--frequency-hz", "3"), "error: profile 'step' has no parameter"),
    (("run", "sine", "--duration", "-1"), "error: --duration must be > 0 s"),
    (("decode", "/nonexistent.log"), "error: no such log: /nonexistent.log"),
    (("plant", "--set", "nope=1"), "error: unknown parameter 'nope'"),
    (("run", "sine", "--rt-priority", "100"), "error: --rt-priority must be within 0..99"),
    (("up", "--rt-priority", "-1"), "error: --rt-priority must be within 0..99"),
])
def test_user_errors_are_one_line(state_env, args, message):
    r = bench(*args, env=state_env, timeout=60)
    assert r.returncode == 2
    assert r.stderr.strip().startswith(message), r.stderr
    assert "Traceback" not in r.stderr


def test_plant_list_params_and_no_bus():
    r = subprocess.run([sys.executable, "-m", "plant_rt", "--list-params"], capture_output=True,
                       text=True, timeout=60, cwd=str(ROOT))
    assert r.returncode == 0
    assert len(r.stdout.strip().splitlines()) == len(PARAMS) + 1
    assert "effects.backlash_m" in r.stdout and "[0, 0.001]" in r.stdout
    env = {**os.environ, "BENCH_STATE_DIR": "/nonexistent-bench-state"}
    r = subprocess.run([sys.executable, "-m", "plant_rt"], capture_output=True, text=True,
                       timeout=60, cwd=str(ROOT), env=env)
    assert r.returncode == 2 and r.stderr.startswith("error: no CAN bus")


@pytest.mark.parametrize("cmd", [
    [sys.executable, "-m", "bench.bus.hub", "--help"],
    [sys.executable, "-m", "plant_rt.eds", "--help"],
    [sys.executable, "-m", "plant_rt", "--help"],
    [sys.executable, str(ROOT / "benchmarks" / "bench_bus.py"), "--help"],
])
def test_helper_scripts_help(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=60, cwd=str(ROOT))
    assert r.returncode == 0, r.stderr
    assert "usage:" in r.stdout


def test_one_bench_per_user_whatever_the_working_directory(tmp_path):
    """Without $BENCH_STATE_DIR and $XDG_RUNTIME_DIR the state was in ./.bench: `bench
    status` in a subfolder said "bench is not up" while it ran, and `bench run` from
    another folder silently started a second hub and plant. Now every folder talks to
    the one bench of the user, and each command says which (its state directory)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items()
           if k not in ("BENCH_STATE_DIR", "XDG_RUNTIME_DIR", "CAN_INTERFACE", "CAN_CHANNEL",
                        "CAN_CONFIG")}
    env.update(TMPDIR=str(tmp), PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    state = tmp / f"ema-bench-{os.getuid()}"
    here, sub, other = tmp_path / "a", tmp_path / "a" / "sub", tmp_path / "b"
    for d in (sub, other):
        d.mkdir(parents=True)

    def run(cwd, *args, timeout=120):
        return subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True,
                              text=True, timeout=timeout, env=env, cwd=str(cwd))

    r = run(here, "up", "--pace", "sync", timeout=180)
    try:
        assert r.returncode == 0, r.stderr
        assert f"state: {state}" in r.stdout
        r = run(sub, "status")
        assert r.returncode == 0, r.stderr
        assert f"state: {state}" in r.stdout and "pace sync" in r.stdout
        r = run(other, "run", "step", "--duration", "0.1", "--no-progress")
        assert r.returncode == 0, r.stderr
        assert "starting a plant" not in r.stderr and "private" not in r.stdout
        assert f"loopback hub of the bench in {state}" in r.stdout
        assert not (here / ".bench").exists() and not (other / ".bench").exists()
    finally:
        r = run(other, "down")
    assert "stopped plant" in r.stdout and "stopped hub" in r.stdout, r.stdout + r.stderr
    assert str(state) in r.stdout
