"""Stale state never hurts: a state record (hub.json, plant.json)
names its process by pid and start-time token; a corrupt or stale record is reported in
one line, removed and ignored; nothing is ever signalled without its identity checked.

No test here sends a real signal to a process it did not start: `os.kill` is replaced by
a recorder that passes only signal 0 (the existence probe) through."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time

import can
import pytest

from ema_contract import transport as T

REAL_KILL = os.kill     # for the teardown of the test's own processes


@pytest.fixture
def state(monkeypatch, tmp_path):
    """An empty private state directory and no bus configured anywhere."""
    for k in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv(T.STATE_ENV, str(tmp_path / "state"))
    monkeypatch.setattr(T, "socketcan_works", lambda channel="vcan0": False)
    monkeypatch.setattr(can, "rc", {})
    (tmp_path / "state").mkdir()
    return tmp_path / "state"


@pytest.fixture
def signals(monkeypatch):
    """Record every signal sent with os.kill; only signal 0 (a probe) really goes out."""
    sent: list[tuple[int, int]] = []
    real = os.kill

    def kill(pid, sig):
        if sig == 0:
            return real(pid, 0)
        sent.append((pid, sig))

    monkeypatch.setattr(os, "kill", kill)
    return sent


@pytest.fixture
def foreign():
    """A live process that is not the bench's (a sleep started by the test)."""
    p = subprocess.Popen(["sleep", "60"])
    yield p
    REAL_KILL(p.pid, signal.SIGKILL)
    p.wait(5)


def _write(state, name, data) -> None:
    text = data if isinstance(data, str) else json.dumps(data)
    (state / name).write_text(text)


CORRUPT = [
    ("{", "not JSON"),
    ("[1, 2]", "not an object"),
    ('"x"', "not an object"),
    ({"port": 1234}, "no pid"),
    ({"pid": 1.5, "port": 1234}, "float pid"),
    ({"pid": True, "port": 1234}, "bool pid"),
    ({"pid": "123", "port": 1234}, "str pid"),
    ({"pid": -5, "port": 1234}, "negative pid"),
    ({"pid": 0, "port": 1234}, "pid 0"),
    ({"pid": 1, "port": 1234}, "pid 1"),
    ({"pid": [7], "port": 1234}, "list pid"),
    ({"pid": "self", "port": "abc"}, "str port"),
    ({"pid": "self", "port": 1.5}, "float port"),
    ({"pid": "self", "port": 70000}, "port out of range"),
    ({"pid": "self", "port": 1234, "start": 5}, "token not a string"),
]


@pytest.mark.parametrize("data,why", CORRUPT, ids=[c[1] for c in CORRUPT])
def test_corrupt_hub_record_is_reported_removed_and_ignored(state, capsys, data, why):
    if isinstance(data, dict) and data.get("pid") == "self":
        data = {**data, "pid": os.getpid()}
    _write(state, T.HUB_FILE, data)
    assert T.read_state(T.HUB_FILE) is None, why
    assert T.hub_url() is None
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"corrupt state file {state / T.HUB_FILE}")
    assert err[0].endswith(": removed")
    assert not (state / T.HUB_FILE).exists()


@pytest.mark.parametrize("data", [{"pid": 1.5, "bus": "x"}, {"pid": 4242, "bus": 7},
                                  {"pid": 4242}, {"pid": 4242, "bus": "x", "log": 3}])
def test_corrupt_plant_record(state, capsys, data):
    _write(state, T.PLANT_FILE, data)
    assert T.read_state(T.PLANT_FILE) is None
    assert capsys.readouterr().err.startswith("corrupt state file")


def test_record_of_a_foreign_live_process_is_stale(state, capsys, foreign):
    """PID reuse: the pid runs, but it is not the process the record was written for."""
    _write(state, T.HUB_FILE, {"pid": foreign.pid, "port": 1234, "start": "0:1"})
    assert T.read_state(T.HUB_FILE) is None
    err = capsys.readouterr().err.strip()
    assert err == (f"stale state file {state / T.HUB_FILE} (pid {foreign.pid} is not the "
                   "bench's hub): removed")
    # no token (an older record): the command line must be the bench's hub
    _write(state, T.PLANT_FILE, {"pid": foreign.pid, "bus": "remote:x"})
    assert T.read_state(T.PLANT_FILE) is None
    assert f"(pid {foreign.pid} is not the bench's plant)" in capsys.readouterr().err
    assert foreign.poll() is None


def test_record_of_a_dead_process_is_stale(state, capsys):
    p = subprocess.Popen(["true"])
    p.wait(5)
    _write(state, T.PLANT_FILE, {"pid": p.pid, "bus": "remote:x", "start": "0:1"})
    assert T.read_state(T.PLANT_FILE) is None
    assert f"(pid {p.pid} is not running): removed" in capsys.readouterr().err
    assert not (state / T.PLANT_FILE).exists()


def test_write_state_records_the_identity(state, capsys, foreign):
    T.write_state(T.PLANT_FILE, {"pid": foreign.pid, "bus": "remote:x"})
    rec = json.loads((state / T.PLANT_FILE).read_text())
    assert rec["start"] == T.process_token(foreign.pid) and rec["start"]
    assert T.read_state(T.PLANT_FILE)["pid"] == foreign.pid     # token matches: the bench's
    assert capsys.readouterr().err == ""
    assert T.process_token(os.getpid()) != rec["start"]


def test_a_stale_record_that_cannot_be_removed_is_reported_once(state, capsys, monkeypatch):
    from pathlib import Path

    def refuse(self, missing_ok=False):
        raise PermissionError(13, "Permission denied", str(self))

    _write(state, T.HUB_FILE, "{")
    monkeypatch.setattr(Path, "unlink", refuse)
    for _ in range(3):
        assert T.read_state(T.HUB_FILE) is None
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].endswith("(not JSON): ignored (cannot remove it: Permission denied)")


def test_remove_state_of_a_corrupt_record_does_not_raise(state):
    _write(state, T.HUB_FILE, "[1]")
    T.remove_state(T.HUB_FILE, 1234)         # the hub's exit path: record not its own


@pytest.mark.parametrize("pid", [0, 1, -1, 1.5, True, "12"])
def test_stop_pid_never_signals_an_invalid_pid(signals, pid):
    from bench.bus.procs import stop_pid
    assert stop_pid(pid, timeout=0.2) is False
    assert signals == []


def test_stop_pid_never_signals_a_foreign_process(signals, foreign):
    from bench.bus.procs import stop_pid
    assert stop_pid(foreign.pid, timeout=0.2, token="0:1") is False
    assert stop_pid(foreign.pid, timeout=0.2) is False       # no identity at all
    assert signals == []
    # the right identity: signalled
    assert stop_pid(foreign.pid, timeout=0.2, token=T.process_token(foreign.pid))
    assert signals and signals[0] == (foreign.pid, signal.SIGTERM)


def _down():
    from bench.cli.updown import cmd_down
    return cmd_down(argparse.Namespace())


def test_down_with_a_float_pid_signals_nothing(state, signals, capsys):
    """`{"pid": 1.5}` once made `bench down` target PID 1."""
    _write(state, T.HUB_FILE, {"pid": 1.5, "port": 1234})
    _write(state, T.PLANT_FILE, {"pid": True, "bus": "remote:x"})
    t0 = time.monotonic()
    assert _down() == 0
    assert signals == []
    err = capsys.readouterr().err
    assert err.count("corrupt state file") == 2 and "Traceback" not in err
    assert time.monotonic() - t0 < 1.0


def test_down_with_a_reused_pid_signals_nothing(state, signals, capsys, foreign):
    _write(state, T.PLANT_FILE, {"pid": foreign.pid, "bus": "remote:x", "start": "0:1"})
    _write(state, T.HUB_FILE, {"pid": os.getpid(), "port": 1234})
    assert _down() == 0
    assert signals == []
    err = capsys.readouterr().err
    assert f"(pid {foreign.pid} is not the bench's plant): removed" in err
    assert f"(pid {os.getpid()} is not the bench's hub): removed" in err
    assert "nothing to stop" in err
    assert not list(state.glob("*.json"))


@pytest.mark.parametrize("text", ["{", '{"pid": "x", "port": 1}', '{"pid": [1], "port": 1}',
                                  '{"pid": 99999999, "port": "y"}', "null"])
def test_status_with_a_corrupt_hub_record_is_one_line(state, capsys, text):
    from bench.cli import main
    _write(state, T.HUB_FILE, text)
    assert main(["status"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2, err
    assert err[0].startswith("corrupt state file") or err[0].startswith("stale state file")
    assert err[1].startswith("error: bench is not up")


def test_find_bus_of_run_with_a_corrupt_hub_record(state, capsys):
    """`bench run` looks for a bus with find_bus; a corrupt record means: none, start one."""
    from bench.bus import find_bus
    _write(state, T.HUB_FILE, '{"pid": {"a": 1}, "port": 5}')
    assert find_bus({}) is None
    assert capsys.readouterr().err.startswith("corrupt state file")


def test_pid_alive_refuses_non_integers():
    for pid in (1.5, True, "1", None):
        assert T.pid_alive(pid) is False
    assert T.pid_alive(os.getpid())


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
