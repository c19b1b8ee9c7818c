"""Bad input over the bus: malformed frames, a killed ECU, a killed plant, corrupted logs."""

from __future__ import annotations

import os
import signal
import sys
import time

import can
import canopen
import pytest
from bus_helpers import (
    BUS_KINDS,
    Collector,
    bench,
    file_size,
    make_env,
    module_bus_env,
    sdo_client,
    spawn,
    wait_until,
)

from bench.bus.logs import read_log, trace_from_log
from bench.signals.trace import Trace
from ema_contract.frames import Frames
from ema_contract.states import NMTCommand, NMTState, StatusWord
from ema_contract.transport import close_bus


@pytest.fixture(scope="module", params=BUS_KINDS)
def bus_env(request, tmp_path_factory):
    yield from module_bus_env(request, tmp_path_factory)


def remote_node(env):
    return sdo_client(env.bus())


def close(network):
    network.notifier.stop(1.0)
    close_bus(network.bus)


def test_malformed_frames_are_counted_and_the_plant_keeps_answering(bus_env):
    f = Frames()
    network, node = remote_node(bus_env)
    bus = network.bus
    try:
        node.nmt.send_command(NMTCommand.RESET_NODE)
        time.sleep(0.3)
        node.nmt.send_command(NMTCommand.START)
        raw = [(0x210, b"\x01\x02"), (0x123, b"\xAA"), (0x7EE, b""), (0x080, b"\x01\x02\x03"),
               (0x610, b"\x40\x00")]
        for cid, data in raw:
            bus.send(can.Message(arbitration_id=cid, data=data, is_extended_id=False))
        bus.send(can.Message(arbitration_id=0x1ABCDEF, data=b"\x00", is_extended_id=True))
        bus.send(f.encode_unchecked("EMA_RPDO1", {"CurrentDemand": float("nan"),
                                                  "ControlWord": 1}))
        bus.send(f.encode("SYNC", {"SYNC_Counter": 1}))
        bus.send(f.encode_unchecked("EMA_RPDO1", {"CurrentDemand": -1e4, "ControlWord": 1}))
        bus.send(f.encode("SYNC", {"SYNC_Counter": 2}))
        time.sleep(0.2)
        st = node.sdo["node_status"]
        assert st["bad_frames"].raw == 3           # RPDO, SYNC and SDO of the wrong length
        assert st["unknown_frames"].raw == 3       # two unknown ids and an extended frame
        assert st["demands_invalid"].raw == 2      # NaN and -10 kA
        assert st["cycles"].raw == 2
        assert st["applied_demand_a"].raw == pytest.approx(-25.0)
        assert st["status_word"].raw & StatusWord.DEMAND_CLAMPED
        with pytest.raises(canopen.SdoAbortedError) as e:
            node.sdo.upload(0x3000, 0)
        assert e.value.code == 0x06020000
    finally:
        node.nmt.send_command(NMTCommand.RESET_NODE)
        close(network)


def _kill_ecu_mid_run(bus_env, watch: Collector, pace: str):
    """`bench run sine` at `pace` against the module's plant, SIGKILLed after 300 SYNCs;
    returns the monotonic time of the kill and how many frames `watch` had seen then."""
    ecu = spawn(sys.executable, "-m", "bench", "run", "sine", "--pace", pace,
                "--duration", "60", *bus_env.flags, env=bus_env.env)
    try:
        wait_until(lambda: watch.ids().count(0x80) > 300, 60, "the ECU's run to start")
    finally:
        ecu.send_signal(signal.SIGKILL)
        seen = len(watch.msgs)
        t_kill = time.monotonic()
        ecu.communicate(timeout=10)
    return t_kill, seen


def test_ecu_killed_mid_run_lockstep_plant_holds_still(bus_env):
    """Lockstep: the heartbeat consumer counts SYNC periods. A dead ECU sends no SYNC, so
    the plant does not move, which is safe; no timeout is declared on wall time."""
    watch = Collector(bus_env)
    network, node = remote_node(bus_env)
    try:
        _, seen = _kill_ecu_mid_run(bus_env, watch, "sync")
        st = node.sdo["node_status"]
        t_plant = st["plant_time_s"].raw
        time.sleep(1.0)                                  # > 3 consumer times of wall time
        assert st["plant_time_s"].raw == t_plant > 0.3
        assert 0x90 not in watch.ids()[seen:]              # no EMCY after the kill
        assert st["heartbeat_timeouts"].raw == 0
        assert not st["status_word"].raw & StatusWord.COMMAND_TIMEOUT
        hb = [m for m in watch.msgs if m.arbitration_id == 0x710]
        assert hb[-1].data[0] == NMTState.OPERATIONAL    # alive, holding still
    finally:
        close(network)
        watch.close()
        node.nmt.send_command(NMTCommand.RESET_NODE)


def test_ecu_killed_mid_run_realtime_plant_leaves_operational_with_one_emcy(bus_env):
    """Real time: the consumer runs on the wall clock (0x1016, 300 ms); the error behaviour
    0x1029 = 0 takes the node to PRE-OPERATIONAL: demand 0, drive disabled, EMCY 0x8130."""
    watch = Collector(bus_env)
    network, node = remote_node(bus_env)
    try:
        t_kill, seen = _kill_ecu_mid_run(bus_env, watch, "realtime")
        wait_until(lambda: 0x90 in watch.ids(), 2.0, "an EMCY after the ECU died")
        assert time.monotonic() - t_kill < 1.0
        wait_until(lambda: [m for m in watch.msgs[seen:] if m.arbitration_id == 0x710
                            and m.data[0] == NMTState.PRE_OPERATIONAL], 1.0,
                   "a PRE-OPERATIONAL heartbeat after the kill")
        st = node.sdo["node_status"]
        t_plant = st["plant_time_s"].raw
        word = st["status_word"].raw
        assert word & StatusWord.COMMAND_TIMEOUT and not word & StatusWord.ENABLED
        assert st["nmt_state"].raw == NMTState.PRE_OPERATIONAL
        assert st["applied_demand_a"].raw == 0.0
        assert st["heartbeat_timeouts"].raw == 1
        time.sleep(0.5)
        assert st["plant_time_s"].raw == t_plant           # the plant stopped
        f = Frames()
        emcy = [f.decode(m)[1] for m in watch.msgs if m.arbitration_id == 0x90]
        names = [f.label("EMA_EMCY", "EMCY_ErrorCode", e["EMCY_ErrorCode"]) for e in emcy]
        assert names.count("heartbeat_lost") == 1 and names[-1] == "heartbeat_lost"
    finally:
        close(network)
        watch.close()
        node.nmt.send_command(NMTCommand.RESET_NODE)


@pytest.fixture
def own_env(tmp_path):
    env = make_env("loopback", tmp_path / "state")
    yield env
    env.stop()


def test_plant_killed_mid_run_ecu_stops_with_a_clear_error_and_a_complete_log(own_env,
                                                                             tmp_path):
    log, saved = tmp_path / "cut.log", tmp_path / "cut.npz"
    ecu = spawn(sys.executable, "-m", "bench", "run", "sine", "--pace", "sync", "--duration",
                "60", "--no-plant", "--log", str(log), "--save", str(saved), *own_env.flags,
                env=own_env.env)
    try:
        wait_until(lambda: file_size(log) > 200_000, 60,
                   "the run to log frames")
        plant = own_env.children[-1]
        os.kill(plant.pid, signal.SIGKILL)
        out, err = ecu.communicate(timeout=60)       # bounds the stop: no hang
    finally:
        if ecu.poll() is None:
            ecu.kill()
            ecu.communicate(timeout=10)
    assert ecu.returncode == 2, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("error: the plant stopped answering at t = "), err
    assert "periods done, log up to there in" in err
    issues = []
    frames = list(read_log(log, issues))
    assert not issues and len(frames) > 1000
    dec = trace_from_log(log)
    part = Trace.load(saved)
    assert part.meta["complete"] is False
    assert abs(len(dec) - len(part)) <= 1 and len(part) > 100
    n = min(len(dec), len(part))
    assert (dec["position_m"][:n - 1] == part["position_m"][:n - 1]).all()


def test_replay_reports_corrupted_lines_and_plays_the_rest(bus_env, tmp_path):
    src = tmp_path / "src.log"
    lines = [f"({1000 + k * 0.001:.6f}) vcan0 181#{k:016X}" for k in range(30)]
    lines[3] = lines[3][:-5]                       # truncated data
    lines[10] = "(1000.0100 vcan0 181#00"          # broken timestamp
    lines[20] = "complete garbage"
    src.write_text("\n".join(lines) + "\n(1000.05) vcan0 1")   # truncated last line
    watch = Collector(bus_env)
    try:
        time.sleep(0.2)
        r = bench("replay", str(src), *bus_env.flags, env=bus_env.env)
        time.sleep(0.3)
    finally:
        watch.close()
    assert r.returncode == 1
    for n in (4, 11, 21, 31):
        assert f"line {n}:" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1] == (
        f"error: {src}: 4 bad lines skipped (--skip-bad plays the rest and exits 0)")
    assert "27 frames played" in r.stdout
    got = [m for m in watch.msgs if m.arbitration_id == 0x181]
    assert len(got) == 27
    assert int.from_bytes(got[-1].data, "big") == 29
    span = got[-1].timestamp - got[0].timestamp
    assert 0.02 < span < 0.5                        # original timing (29 ms) kept, roughly
    r = bench("replay", str(src), "--skip-bad", "--speed", "0", *bus_env.flags,
              env=bus_env.env)
    assert r.returncode == 0


@pytest.mark.parametrize("content", [b"", bytes(range(256)) * 4], ids=["empty", "binary"])
def test_replay_of_a_file_with_no_frame_is_an_error(bus_env, tmp_path, content):
    """An empty log played "0 frames" with exit 0; a binary one printed its lines' faults
    and exit 1 with no error line."""
    src = tmp_path / "x.log"
    src.write_bytes(content)
    r = bench("replay", str(src), "--speed", "0", *bus_env.flags, env=bus_env.env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith(f"error: {src}: no frame to play")


def test_bench_log_records_the_bus(bus_env, tmp_path):
    out = tmp_path / "rec.log"
    rec = spawn(sys.executable, "-m", "bench", "log", str(out), "--duration", "4",
                *bus_env.flags, env=bus_env.env)
    bus = bus_env.bus()
    try:
        # the recorder says "recording ..." once its bus is open (start-up takes seconds
        # on a loaded machine: a fixed sleep lost the frames)
        line = ""
        end = time.monotonic() + 60
        while "recording" not in line and time.monotonic() < end and rec.poll() is None:
            line = rec.stderr.readline()
        assert "recording" in line, line
        for k in range(20):
            bus.send(can.Message(arbitration_id=0x555, data=bytes([k]), is_extended_id=False))
        o, e = rec.communicate(timeout=20)
    finally:
        close_bus(bus)
        if rec.poll() is None:
            rec.kill()
            rec.communicate(timeout=10)
    assert rec.returncode == 0, e
    got = [m for m in read_log(out) if m.arbitration_id == 0x555]
    assert [m.data[0] for m in got] == list(range(20))
