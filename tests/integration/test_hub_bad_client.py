"""A misbehaving client on the loopback hub during a lockstep run of the plant and the
ECU (items 6-7): every bad event is answered or its client dropped, nothing of
it reaches the bus, and the run is the same, period by period, as an undisturbed one."""

from __future__ import annotations

import sys
import threading
from collections import Counter
from pathlib import Path

import numpy as np
from bus_helpers import make_env

from bench.ecu import run_over_bus
from bench.profiles.catalog import make_profile

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "unit"))
from test_hub_events import (  # noqa: E402
    BAD_EVENTS,
    BAD_REQUESTS,
    OP_BINARY,
    Closed,
    RawClient,
)

SIGNALS = ("current_demand_a", "current_a", "motor_speed_rad_s", "motor_angle_rad",
           "position_m", "status_word")


def misbehave(port: int, stop: threading.Event, seen: Counter, rounds: int = 100) -> None:
    """Every bad event, bad bus_request and broken stream of the unit tests, in turn,
    until `stop` (at most `rounds` rounds); counts the hub's answers in `seen`."""
    slow = RawClient(port, rcvbuf=4096)                 # connected, never reads
    listener = RawClient(port, config={"can_filters": [
        {"can_id": i, "can_mask": 0x7FF} for i in range(256)]})
    try:
        for _ in range(rounds):
            if stop.is_set():
                return
            bad = RawClient(port)
            for kind, payload in BAD_EVENTS.values():
                bad.send_event(kind, payload)
            assert bad.sync()
            seen["errors"] += len(bad.errors())
            bad.close()
            for payload in BAD_REQUESTS.values():
                c = RawClient(port, request=False)
                c.send_event("bus_request", payload)
                seen[f"close {c.close_code()}"] += 1
                c.close()
            c = RawClient(port)
            c.send_frame(OP_BINARY, b"", length=2**62)
            seen[f"close {c.close_code()}"] += 1
            c.close()
            seen["rounds"] += 1
    except (Closed, OSError, AssertionError) as exc:
        seen[f"failed: {type(exc).__name__}: {exc}"] += 1
    finally:
        seen["slow alive"] += slow.sync()
        seen["listener alive"] += listener.sync()
        slow.close()
        listener.close()


def test_plant_and_ecu_run_on_unharmed_while_a_client_misbehaves(tmp_path):
    env = make_env("loopback", tmp_path / "state")
    try:
        port = int(env.cfg["channel"].rsplit(":", 1)[1].strip("/"))
        profile = make_profile("sine", duration_s=0.3)
        values = {"effects.backlash_m": 30e-6, "sensors.noise": True, "sensors.noise_seed": 3}
        calm = run_over_bus(profile, values=values, pace="sync", settings=env.cfg)
        stop, seen = threading.Event(), Counter()
        th = threading.Thread(target=misbehave, args=(port, stop, seen), daemon=True)
        th.start()
        try:
            noisy = run_over_bus(profile, values=values, pace="sync", settings=env.cfg)
        finally:
            stop.set()
            th.join(30)
        assert not th.is_alive()
        assert not [k for k in seen if k.startswith("failed")], seen
        assert seen["rounds"] >= 1 and seen["errors"] == seen["rounds"] * len(BAD_EVENTS)
        assert seen["close 1008"] == seen["rounds"] * len(BAD_REQUESTS)
        assert seen["close 1009"] == seen["rounds"]
        assert seen["slow alive"] == seen["listener alive"] == 1
        assert noisy.meta["complete"] and len(noisy) == len(calm) == 300
        for col in SIGNALS:
            np.testing.assert_array_equal(noisy[col], calm[col], err_msg=col)
        pc = noisy.meta["plant_counters"]
        assert pc["bad_frames"] == pc["unknown_frames"] == 0   # nothing of it reached the bus
        assert env.children[0].alive()
    finally:
        env.stop()
