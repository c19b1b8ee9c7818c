"""`bench up`/`down`/`status`/`run` against stale and corrupt state and against each other:
a lock makes two concurrent `bench up` start one hub and one plant;
a record whose pid now runs another program is stale, never signalled; a corrupt record
is reported in one line. Every process a test starts is stopped by its pid."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from bus_helpers import ROOT, bench, wait_until

MODULES = {"hub": "bench.bus.hub", "plant": "plant_rt"}


def bench_processes(state: Path) -> dict[str, list[int]]:
    """pids of the hubs and plants running with BENCH_STATE_DIR=state (found in /proc)."""
    found: dict[str, list[int]] = {k: [] for k in MODULES}
    mark = f"BENCH_STATE_DIR={state}".encode()
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            env = (d / "environ").read_bytes().split(b"\0")
            argv = (d / "cmdline").read_bytes().split(b"\0")
            st = (d / "stat").read_text().rsplit(")", 1)[-1].split()[0]
        except OSError:
            continue
        if mark not in env or st == "Z":
            continue
        for role, module in MODULES.items():
            if module.encode() in argv:
                found[role].append(int(d.name))
    return found


def kill_all(pids: dict[str, list[int]]) -> None:
    for group in pids.values():
        for pid in group:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


@pytest.fixture
def state_env(tmp_path):
    state = tmp_path / "state"
    env = {**os.environ, "BENCH_STATE_DIR": str(state)}
    for k in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_CONFIG"):
        env.pop(k, None)
    yield env, state
    bench("down", env=env, timeout=60)
    kill_all(bench_processes(state))          # whatever `down` could not stop


@pytest.fixture
def foreign():
    """A live process that is not the bench's."""
    p = subprocess.Popen(["sleep", "120"])
    yield p
    p.kill()
    p.wait(5)


def test_two_concurrent_ups_start_one_hub_and_one_plant(state_env):
    env, state = state_env
    cmd = [sys.executable, "-m", "bench", "up", "--pace", "sync"]
    procs = [subprocess.Popen(cmd, env=env, cwd=str(ROOT), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=240) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outs
    stdout = [o[0] for o in outs]
    assert sum("plant: pid" in s for s in stdout) == 1, outs
    assert sum("already up" in s for s in stdout) == 1, outs
    running = bench_processes(state)
    assert (len(running["hub"]), len(running["plant"])) == (1, 1), running
    r = bench("down", env=env, timeout=60)
    assert r.returncode == 0 and "stopped plant" in r.stdout and "stopped hub" in r.stdout
    assert wait_until(lambda: bench_processes(state) == {"hub": [], "plant": []}, 10,
                      "hub and plant to exit")


def test_up_ignores_a_stale_plant_record_of_a_reused_pid(state_env, foreign):
    """plant.json names a pid that now runs another program: `bench up` must not say
    "already up"; `bench down` must not signal that program."""
    env, state = state_env
    state.mkdir()
    (state / "plant.json").write_text(json.dumps({"pid": foreign.pid, "bus": "remote:x"}))
    r = bench("up", "--pace", "sync", env=env, timeout=180)
    assert r.returncode == 0, r.stderr
    assert "already up" not in r.stdout and "plant: pid" in r.stdout
    assert (f"stale state file {state / 'plant.json'} (pid {foreign.pid} is not the bench's "
            "plant): removed") in r.stderr
    rec = json.loads((state / "plant.json").read_text())
    assert rec["pid"] != foreign.pid and rec["pid"] in bench_processes(state)["plant"]
    r = bench("down", env=env, timeout=60)
    assert r.returncode == 0 and "stopped plant" in r.stdout
    assert foreign.poll() is None


def test_down_never_signals_the_process_of_a_stale_hub_record(state_env, foreign):
    env, state = state_env
    state.mkdir()
    (state / "hub.json").write_text(json.dumps({"pid": foreign.pid, "port": 1}))
    r = bench("down", env=env, timeout=60)
    time.sleep(0.2)
    assert foreign.poll() is None, "bench down killed a process that was not the bench's"
    assert r.returncode == 0
    assert f"(pid {foreign.pid} is not the bench's hub): removed" in r.stderr
    assert "nothing to stop" in r.stderr and "Traceback" not in r.stderr
    assert not (state / "hub.json").exists()


CORRUPT = ['{"pid": ', '["hub"]', '{"pid": "12", "port": 5}', '{"pid": 99999999, "port": []}']


@pytest.mark.parametrize("text", CORRUPT)
def test_corrupt_hub_record_in_status_and_down(state_env, text):
    env, state = state_env
    for cmd in ("status", "down"):
        state.mkdir(exist_ok=True)
        (state / "hub.json").write_text(text)
        r = bench(cmd, env=env, timeout=60)
        err = r.stderr.strip().splitlines()
        assert "Traceback" not in r.stderr and len(err) == 2, (cmd, r.stderr)
        assert err[0].startswith(f"corrupt state file {state / 'hub.json'}")
        assert err[0].endswith(": removed")
        assert r.returncode == (2 if cmd == "status" else 0)


def test_corrupt_hub_record_in_up_and_run(state_env, tmp_path):
    env, state = state_env
    state.mkdir()
    (state / "hub.json").write_text('{"pid": [1], "port": "x"}')
    r = bench("run", "step", "--pace", "sync", "--duration", "0.05", "--no-progress",
              env=env, timeout=180)
    assert r.returncode == 0, r.stderr
    assert r.stderr.startswith("corrupt state file") and "Traceback" not in r.stderr
    assert "50 periods" in r.stdout
    (state / "hub.json").write_text("{{{")
    r = bench("up", "--pace", "sync", env=env, timeout=180)
    assert r.returncode == 0, r.stderr
    assert r.stderr.startswith("corrupt state file") and "hub: pid" in r.stdout
    assert json.loads((state / "hub.json").read_text())["pid"] in bench_processes(state)["hub"]
