"""The logs of the hub and plant a command starts for itself: removed
when the command ends well, kept and named in the error when it fails, and the run
directory never grows past a bound."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from bus_helpers import bench

from bench import BenchError
from bench.bus import session


@pytest.fixture
def state(tmp_path, monkeypatch):
    for k in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_CONFIG"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("BENCH_STATE_DIR", str(tmp_path / "state"))
    return tmp_path / "state"


def _files(d):
    return sorted(p.name for p in d.iterdir()) if d.exists() else []


def test_runs_leave_no_files_behind(state):
    env = {**os.environ, "BENCH_STATE_DIR": str(state)}
    for _ in range(2):
        r = bench("run", "step", "--pace", "sync", "--duration", "0.02", "--no-progress",
                  env=env, timeout=180)
        assert r.returncode == 0, r.stderr
        assert _files(state / "run") == []


def test_a_session_that_fails_keeps_its_logs_and_names_them(state):
    from bench.bus.procs import run_dir
    with pytest.raises(BenchError) as err:
        with session({}) as sess:
            hub_log = sess.children[0].log_path
            raise BenchError("the plant stopped answering")
    msg = str(err.value)
    assert msg.startswith("the plant stopped answering; logs of the processes started for "
                          "this command: ")
    assert str(hub_log) in msg and hub_log.exists()
    with session({}):
        pass
    assert _files(run_dir()) == [hub_log.name]


def test_the_run_directory_is_bounded(state):
    from bench.bus.procs import KEEP_RUN_LOGS, run_dir
    d = run_dir()
    d.mkdir(parents=True)
    gone = int(Path("/proc/sys/kernel/pid_max").read_text()) + 1     # pids no process can have
    for k in range(KEEP_RUN_LOGS + 15):        # logs of failed runs of benches now gone
        p = d / f"plant-{gone + k}.log"
        p.write_text("x")
        os.utime(p, (1e9 + k, 1e9 + k))
    other = subprocess.Popen(["sleep", "60"])  # a bench still running: its log stays
    try:
        live = d / f"hub-{other.pid}.log"
        live.write_text("x")
        os.utime(live, (1e8, 1e8))
        with session({}):
            pass
        left = _files(d)
    finally:
        other.kill()
        other.wait(5)
    assert live.name in left and len(left) == KEEP_RUN_LOGS + 1, left
    assert f"plant-{gone + KEEP_RUN_LOGS + 14}.log" in left     # the newest kept
    assert f"plant-{gone}.log" not in left                       # the oldest removed
