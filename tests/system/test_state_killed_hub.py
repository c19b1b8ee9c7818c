"""Clients of a hub that is killed under them: one `error:` line, exit
code != 0, and no `BusABC.__del__` traceback or "was not properly shut down" at exit."""

from __future__ import annotations

import os
import select
import sys
import time

import pytest
from bus_helpers import spawn

from bench.bus.procs import start_hub

NOISE = ("Traceback", "Exception ignored", "not properly shut down")


def _wait_for_line(stream, needle: str, timeout: float) -> str:
    """Read `stream` line by line until one contains `needle` (bounded)."""
    end = time.monotonic() + timeout
    seen = ""
    while time.monotonic() < end:
        ready, _, _ = select.select([stream], [], [], 0.1)
        if ready:
            line = stream.readline()
            seen += line
            if needle in line or not line:
                return seen
    raise AssertionError(f"no {needle!r} within {timeout} s: {seen!r}")


@pytest.fixture
def hub(tmp_path, monkeypatch):
    monkeypatch.setenv("BENCH_STATE_DIR", str(tmp_path / "state"))
    h = start_hub(persistent=False)
    yield h
    h.stop()


def _killed_under(hub, tmp_path, args: tuple[str, ...], ready: str, timeout: float):
    """Start `python -m ARGS` on the hub's bus, kill the hub once `ready` is printed:
    the exit status and the standard error."""
    env = {**os.environ, "BENCH_STATE_DIR": str(tmp_path / "state")}
    p = spawn(sys.executable, "-m", *args, "-i", "remote", "-c", hub.info["url"], env=env)
    try:
        _wait_for_line(p.stderr, ready, timeout)
        hub.proc.kill()
        out, err = p.communicate(timeout=30)
    finally:
        p.kill()
        p.wait(5)
    return p.returncode, err


def test_bench_log_when_the_hub_is_killed(hub, tmp_path):
    rc, err = _killed_under(hub, tmp_path, ("bench", "log", str(tmp_path / "x.log"),
                                            "--duration", "60"), "recording", 60)
    assert rc == 2, err
    assert err.strip().startswith("error: the bus failed after 0 frames"), err
    assert len(err.strip().splitlines()) == 1, err
    assert not any(n in err for n in NOISE), err


def test_plant_when_the_hub_is_killed(hub, tmp_path):
    rc, err = _killed_under(hub, tmp_path, ("plant_rt", "--pace", "sync"), "plant: node", 120)
    assert rc != 0, err
    assert err.strip().startswith("error:"), err
    assert not any(n in err for n in NOISE), err
