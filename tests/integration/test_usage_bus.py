"""Usage over the bus ("Usage"): the actuator's identity read by SDO during the
ECU's set-up and found again in the log; the live usage of a run equal to `bench usage`
on its log; a node without the identity object gives "unknown"."""

from __future__ import annotations

import json
import math

import pytest
from bus_helpers import make_env, watch_a_run
from test_minimal_node import start_minimal_node

from bench.bus.logs import read_log, trace_from_log
from bench.cli import main as bench_main
from bench.ecu import run_over_bus
from bench.hums.live import LiveHums
from bench.profiles.catalog import make_profile
from bench.usage import usage_of_trace

SERIAL = 305419896      # 0x12345678


@pytest.fixture(scope="module")
def serial_env(tmp_path_factory):
    """A loopback hub and a lockstep plant started with --serial."""
    env = make_env("loopback", tmp_path_factory.mktemp("state"), serial=SERIAL)
    yield env
    env.stop()


def test_serial_in_the_log_and_live_usage_equals_the_log(serial_env, tmp_path, capsys):
    log, live_json = tmp_path / "run.log", tmp_path / "live.json"
    values = {"load.kind": "sine", "load.amplitude_n": 3000.0, "load.frequency_hz": 3.0,
              "sensors.noise": True, "sensors.noise_seed": 3}
    tr, rc, w_out, w_err = watch_a_run(serial_env, ["--usage", str(live_json)],
                                       make_profile("sine", cycles=3), values, log)
    assert rc == 0, w_err
    assert "usage run 1" in w_out and str(SERIAL) in w_out
    assert tr.meta["node"]["identity"]["serial"] == SERIAL
    assert tr.meta["actuator_serial"] == str(SERIAL)
    dec = trace_from_log(log)
    assert dec.meta["actuator_serial"] == str(SERIAL)      # from the SDO exchange in the log

    offline = usage_of_trace(dec)
    assert offline.actuator_serial == str(SERIAL)
    assert offline.screw_revolutions > 0.1 and offline.reversals >= 5
    assert offline.life_consumed > 0 and offline.load_cycles >= 3

    # the live accumulator, fed the log's frames as a watcher gets them
    hums = LiveHums(0.5, position_kp_rad_s_per_m=20.0)   # (no gain fit: usage only)
    hums.feed_all(read_log(log))
    hums.finish()
    runs = hums.usage.runs()
    assert len(runs) == 1
    live = runs[0]
    assert live.actuator_serial == str(SERIAL)
    a, b = live.as_dict(), offline.as_dict()
    assert a.keys() == b.keys()
    for k in a:
        assert a[k] == pytest.approx(b[k], rel=1e-9, abs=1e-15) or (
            math.isnan(a[k]) and math.isnan(b[k])), k
    assert (live.load_spectrum_rev == pytest.approx(offline.load_spectrum_rev, rel=1e-9))
    assert (live.position_rainflow == offline.position_rainflow).all()
    # and the watcher that listened to the run live: its totals at the end
    watched = json.loads(live_json.read_text())
    assert len(watched["runs"]) == 1
    total = watched["actuators"][str(SERIAL)]
    for k, v in b.items():
        if math.isfinite(v):
            assert total[k] == pytest.approx(v, rel=1e-9, abs=1e-15), k
    assert total["load_spectrum_rev"] == pytest.approx(offline.load_spectrum_rev.tolist())

    # `bench usage` on the log (in-process): the same numbers, accumulated by serial
    out = tmp_path / "usage.json"
    assert bench_main(["usage", str(log), "--json", str(out), "--by-actuator"]) == 0
    text = capsys.readouterr().out
    assert str(SERIAL) in text
    doc = json.loads(out.read_text())
    assert doc["runs"][0]["life_consumed"] == pytest.approx(offline.life_consumed, rel=1e-12)
    assert doc["actuators"][str(SERIAL)]["screw_revolutions"] == pytest.approx(
        offline.screw_revolutions, rel=1e-12)


@pytest.fixture(scope="module")
def anonymous_env(tmp_path_factory):
    """A loopback hub with the minimal node (CiA 301 only) without 0x1018."""
    state = tmp_path_factory.mktemp("state")
    env = make_env("loopback", state, plant=False)
    try:
        env.children.append(start_minimal_node(env.cfg, state, "--no-identity"))
        yield env
    finally:
        env.stop()


def test_a_node_without_identity_is_unknown(anonymous_env, tmp_path):
    log = tmp_path / "anon.log"
    tr = run_over_bus(make_profile("sine", cycles=1), pace="sync", settings=anonymous_env.cfg,
                      log_path=log, sync_driven=True, start_plant=False)
    assert "serial" not in tr.meta["node"]["identity"]
    assert any(m.startswith("0x1018") for m in tr.meta["node"]["missing"])
    assert tr.meta["actuator_serial"] == "unknown"
    dec = trace_from_log(log)
    assert dec.meta["actuator_serial"] == "unknown"
    assert usage_of_trace(dec).actuator_serial == "unknown"
