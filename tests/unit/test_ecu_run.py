"""The ECU's run against the real plant node on an in-process virtual bus:
a plant that reports a condition changing its behaviour ends the run as a failure, the
heartbeat follows the SYNC grid in lockstep, a second SYNC producer is refused (before
anything is sent) or aborts the run, an abort leaves the node PRE-OPERATIONAL, and a
log that cannot be written is reported as such, with the partial trace kept."""

from __future__ import annotations

import errno
import threading
import time
import uuid

import can
import canopen
import numpy as np
import pytest
from bus_helpers import sdo_client as bus_sdo_client

from bench import BenchError
from bench.bus.logs import trace_from_log
from bench.ecu import Ecu, run_over_bus
from bench.profiles.catalog import make_profile
from ema_contract.frames import Frames
from ema_contract.states import NMTCommand, NMTState, Pace, StatusWord
from ema_contract.transport import close_bus
from plant_rt.model import Plant
from plant_rt.node import PlantNode
from plant_rt.params import PlantParams

SYNC, NMT, SDO_RX, ECU_HB, SETPOINT, RPDO1 = 0x080, 0x000, 0x610, 0x701, 0x181, 0x210


@pytest.fixture(scope="module", autouse=True)
def compiled_plant():
    """The plant kernel compiled (numba, cached on disk) before any node runs."""
    p = Plant(PlantParams())
    p.step(0.0)
    p.measure()


class Rig:
    """A lockstep plant node in a thread and a candump-like watcher on one virtual bus."""

    def __init__(self) -> None:
        self.chan = f"ecu-{uuid.uuid4().hex}"
        self.cfg = {"interface": "virtual", "channel": self.chan}
        self.nbus = can.Bus(interface="virtual", channel=self.chan)
        self.node = PlantNode(self.nbus, PlantParams(), pace=Pace.SYNC)
        self.th = threading.Thread(target=self.node.run, daemon=True)
        self.th.start()
        self.frames = Frames()
        self.wbus = can.Bus(interface="virtual", channel=self.chan)
        self.msgs: list[can.Message] = []
        self.notifier = can.Notifier(self.wbus, [self.msgs.append], timeout=0.02)
        self.buses: list[can.BusABC] = []
        self.ecu: Ecu | None = None
        until(lambda: self.node.state == NMTState.PRE_OPERATIONAL, 3.0, "the node's boot")

    def bus(self) -> can.BusABC:
        b = can.Bus(interface="virtual", channel=self.chan)
        self.buses.append(b)
        return b

    def new_ecu(self, **kw) -> Ecu:
        self.ecu = Ecu(self.bus(), **kw)
        return self.ecu

    def ids_since(self, start: int) -> list[int]:
        return [m.arbitration_id for m in self.msgs[start:]]

    def close(self) -> None:
        if self.ecu is not None:
            self.ecu.close()
        self.node.stop()
        self.th.join(2.0)
        self.notifier.stop(1.0)
        for b in [*self.buses, self.wbus, self.nbus]:
            close_bus(b)


def until(pred, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = pred()
        if got:
            return got
        time.sleep(0.005)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.close()


def prepared(rig: Rig, **kw) -> tuple[Ecu, PlantParams]:
    ecu = rig.new_ecu(**kw)
    return ecu, ecu.prepare(Pace.SYNC, {})


def sdo_client(rig: Rig) -> tuple[canopen.Network, canopen.RemoteNode]:
    return bus_sdo_client(rig.bus(), poll_s=0.02)


# -- item 1: a plant condition that changes its behaviour is never a success ---------------
def test_command_timeout_reported_by_the_plant_fails_the_run(rig):
    """The plant's heartbeat consumer latches a command timeout mid-run (consumer time
    set to 1 ms by a third client): status bit 4 and EMCY 0x8130, demand forced to 0.
    Unfixed, the ECU ignored both and returned a complete trace."""
    ecu, params = prepared(rig)
    net, node = sdo_client(rig)

    def on_period(k: int) -> None:
        if k == 50:
            node.sdo[0x1016][1].raw = (0x01 << 16) | 1     # ECU 0x01, 1 ms

    try:
        with pytest.raises(BenchError, match=r"command timeout.* at t = 0\.\d+ s \(SYNC \d+\)"):
            ecu.run(make_profile("step", duration_s=0.4), params, pace=Pace.SYNC,
                    on_period=on_period)
    finally:
        net.notifier.stop(1.0)
    part = ecu.partial
    assert part is not None and 50 <= len(part) < 400
    assert part.meta["complete"] is False
    assert "heartbeat_lost" in [e["name"] for e in part.meta["emcy"]] or \
        int(part["status_word"][-1]) & StatusWord.COMMAND_TIMEOUT
    # the abort left the node PRE-OPERATIONAL, not OPERATIONAL with the drive off
    until(lambda: rig.node.state == NMTState.PRE_OPERATIONAL, 1.0, "NMT pre-operational")


def test_a_stalled_ecu_in_lockstep_is_never_a_silent_success(rig):
    """The case: the ECU stalls 0.45 s mid-run (GC, JIT, loaded machine). A plant
    that counts its consumer time in SYNC periods lets the run go on; one that counts wall
    time latches a command timeout. Either way, a run that ends as a success must carry
    no command timeout."""
    ecu, params = prepared(rig)

    def on_period(k: int) -> None:
        if k == 100:
            time.sleep(0.45)

    try:
        tr = ecu.run(make_profile("step", duration_s=0.3), params, pace=Pace.SYNC,
                     on_period=on_period)
    except BenchError as exc:
        assert "command timeout" in str(exc)
        return
    words = tr["status_word"].astype(int)
    assert not (words & int(StatusWord.COMMAND_TIMEOUT)).any(), "success with a timeout"
    assert "heartbeat_lost" not in [e["name"] for e in tr.meta["emcy"]]


def test_a_stall_during_set_up_does_not_fail_the_run(rig):
    """The ECU's heartbeat goes on during set-up (another ECU must see it); a stall there
    (0.45 s, a loaded machine) may latch a command timeout before any demand of the run is
    in force: the first RPDO's fault-reset edge clears it, and from SYNC 1 (where the
    first demand applies) the run is clean and valid."""
    ecu = rig.new_ecu()
    ecu.start_heartbeat()
    params = ecu.prepare(Pace.SYNC, {})
    until(lambda: ECU_HB in rig.ids_since(0), 1.0, "a set-up heartbeat")
    ecu.stop_heartbeat()
    time.sleep(0.4)
    tr = ecu.run(make_profile("step", duration_s=0.05), params, pace=Pace.SYNC)
    words = tr["status_word"].astype(int)
    assert tr.meta["complete"]
    assert not (words[1:] & int(StatusWord.COMMAND_TIMEOUT)).any()
    assert (words[1:] & int(StatusWord.ENABLED)).all()     # every demand in force


def test_the_controller_is_loaded_before_the_first_heartbeat(rig, monkeypatch):
    """The first ECU heartbeat arms the node's consumer (0x1016). Loading the controller's
    compiled step holds the interpreter lock for about 0.1 s (0.3-0.5 s on a loaded
    machine), which starved the set-up heartbeat thread and let the plant latch a timeout
    before the run: the ECU loads it before its first heartbeat."""
    import bench.sim.control as control
    events: list[str] = []
    step = control.controller_step

    def recorded_step(*a):
        events.append("step")
        return step(*a)

    monkeypatch.setattr(control, "controller_step", recorded_step)
    ecu = rig.new_ecu()
    beat = ecu.heartbeat

    def recorded_beat(*a, **kw):
        events.append("heartbeat")
        return beat(*a, **kw)

    ecu.heartbeat = recorded_beat
    ecu.start_heartbeat()
    until(lambda: "heartbeat" in events, 1.0, "a set-up heartbeat")
    ecu.stop_heartbeat()
    assert events[0] == "step"


def test_no_full_garbage_collection_while_the_node_watches_the_heartbeat(rig, monkeypatch):
    """A full collection holds the interpreter lock (0.1 s here, 0.3 s in a loaded test
    worker): none between the set-up and the run's end. The loop's collections still skip
    what existed before the run (frozen)."""
    import gc
    collections: list[int] = []
    frozen: list[int] = []
    monkeypatch.setattr(gc, "collect", lambda *a: collections.append(1) or 0)
    ecu, params = prepared(rig)
    tr = ecu.run(make_profile("step", duration_s=0.02), params, pace=Pace.SYNC,
                 on_period=lambda k: frozen.append(gc.get_freeze_count()))
    assert tr.meta["complete"]
    assert collections == []
    assert frozen and min(frozen) > 0
    assert gc.get_freeze_count() == 0          # unfrozen after the run


def test_reporting_conditions_keep_the_run_valid(rig):
    """Over-current (the drive at its current limit, normal in a 40 mm step) is reported
    in the status word and by EMCY, and the run stays a success."""
    ecu, params = prepared(rig)
    tr = ecu.run(make_profile("step", duration_s=0.3), params, pace=Pace.SYNC)
    words = tr["status_word"].astype(int)
    assert tr.meta["complete"] and (words & int(StatusWord.OVERCURRENT)).any()
    assert "overcurrent" in [e["name"] for e in tr.meta["emcy"]]


@pytest.mark.parametrize("label, expect", [
    ("plant_fault", r"plant fault .*EMCY 0x6200 plant_fault"),
    ("pdo_length", r"RPDO of the wrong length .*EMCY 0x8210 pdo_length"),
    (0x5432, r"emergency 0x5432 unknown to the bench"),
])
def test_an_emcy_that_changes_the_plant_behaviour_fails_the_run(rig, label, expect):
    """An EMCY outside over-current, end of stroke, over-temperature and the all-clear
    (here injected on the plant's EMCY id) fails the run, whatever the status word."""
    ecu, params = prepared(rig)
    other = rig.bus()
    f = rig.frames
    code = label if isinstance(label, int) else f.choice("EMA_EMCY", "EMCY_ErrorCode", label)

    def on_period(k: int) -> None:
        if k == 30:
            other.send(f.encode("EMA_EMCY", {"EMCY_ErrorCode": code, "EMCY_ErrorRegister": 1,
                                             "EMCY_StatusWord": 0, "EMCY_Cycle": k}))

    with pytest.raises(BenchError, match=expect):
        ecu.run(make_profile("step", duration_s=0.3), params, pace=Pace.SYNC,
                on_period=on_period)
    assert 30 <= len(ecu.partial) <= 34
    assert code in [e["code"] for e in ecu.partial.meta["emcy"]]


def test_the_demand_stays_within_the_plants_current_limit(rig):
    """`--set motor.current_max_a=10`: the ECU sends its demand saturated at the limit it
    read back, so the plant never has to clamp it (status bit 5 would fail the run)."""
    ecu = rig.new_ecu()
    params = ecu.prepare(Pace.SYNC, {"motor.current_max_a": 10.3})
    tr = ecu.run(make_profile("step", duration_s=0.2), params, pace=Pace.SYNC)
    words = tr["status_word"].astype(int)
    assert tr.meta["complete"] and not (words & int(StatusWord.DEMAND_CLAMPED)).any()
    assert np.max(np.abs(tr["current_demand_a"])) == pytest.approx(10.3, abs=1e-5)
    assert tr.meta["plant_counters"]["demands_invalid"] == 0


def test_lockstep_heartbeat_follows_the_sync_grid(rig):
    """In lockstep the ECU's heartbeat goes out every heartbeat period's worth of SYNCs
    (100), whatever the wall clock says: here the ECU's clock runs 100 times slow, as a
    lockstep run 100 times faster than real time would see it."""
    ecu, params = prepared(rig)
    t0 = time.monotonic()
    ecu._clock = lambda: t0 + (time.monotonic() - t0) / 100.0
    start = len(rig.msgs)
    tr = ecu.run(make_profile("step", duration_s=0.45), params, pace=Pace.SYNC)
    assert tr.meta["complete"]
    ids = [i for i in rig.ids_since(start) if i in (SYNC, ECU_HB)]
    syncs_since_hb, worst = 0, 0
    for i in ids:
        if i == ECU_HB:
            worst, syncs_since_hb = max(worst, syncs_since_hb), 0
        else:
            syncs_since_hb += 1
    worst = max(worst, syncs_since_hb)
    assert ids.count(SYNC) == 450
    assert worst <= 100, f"{worst} SYNCs without an ECU heartbeat"


# -- item 2: two ECUs on one plant ----------------------------------------------------------
def test_a_second_ecu_is_refused_before_it_sends_anything(rig):
    """Another producer's SYNCs on the bus: the run is refused with a clear message, and
    the ECU sent no NMT, SDO, heartbeat or process data (the other run is untouched)."""
    other = rig.bus()
    task = other.send_periodic(rig.frames.encode("SYNC", {"SYNC_Counter": 1}), 0.002)
    try:
        until(lambda: SYNC in rig.ids_since(0), 1.0, "the other producer's SYNC")
        start = len(rig.msgs)
        with pytest.raises(BenchError, match=r"another ECU is driving node 0x10 \(SYNC "
                                             r"from another producer\); stop it first"):
            run_over_bus(make_profile("step", duration_s=0.05), pace="sync",
                         settings=rig.cfg, start_plant=False)
    finally:
        task.stop()
    sent = set(rig.ids_since(start)) - {SYNC, 0x710}
    assert not sent & {NMT, SDO_RX, ECU_HB, SETPOINT, RPDO1}, sorted(map(hex, sent))
    assert rig.node.state == NMTState.PRE_OPERATIONAL


def test_an_ecu_setting_the_node_up_is_seen_by_a_second_one(rig):
    """The first ECU has not sent a SYNC yet (it is writing parameters): its heartbeat,
    which goes on during set-up, is enough for the second one to stay away."""
    first = rig.new_ecu()
    first.start_heartbeat()
    until(lambda: ECU_HB in rig.ids_since(0), 1.0, "the first ECU's heartbeat")
    start = len(rig.msgs)
    with pytest.raises(BenchError, match=r"another ECU is driving node 0x10 "
                                         r"\(ECU_Heartbeat from another producer\)"):
        run_over_bus(make_profile("step", duration_s=0.05), pace="sync", settings=rig.cfg,
                     start_plant=False)
    first.stop_heartbeat()
    assert not set(rig.ids_since(start)) & {NMT, SDO_RX}


def test_own_frames_echoed_by_the_bus_are_not_another_ecu(rig):
    """With ``echo`` (the bus returns the ECU's own frames for the log) the ECU does not
    mistake its own SYNC, set-point, RPDO or heartbeat for another producer's."""
    ecu = Ecu(can.Bus(interface="virtual", channel=rig.chan, receive_own_messages=True),
              echo=True)
    rig.ecu = ecu
    rig.buses.append(ecu.bus)
    ecu.claim()
    ecu.start_heartbeat()
    params = ecu.prepare(Pace.SYNC, {})
    tr = ecu.run(make_profile("step", duration_s=0.3), params, pace=Pace.SYNC)
    assert tr.meta["complete"] and ecu.foreign is None


@pytest.mark.parametrize("echo", [False, True])
def test_the_run_trace_is_its_decoded_log(rig, tmp_path, echo):
    """One row assembler: the trace a bus run returns is, column by column and
    bit for bit, the trace `bench decode` makes of its log, with the ECU's own frames
    logged as sent or as the bus echoes them."""
    log = tmp_path / "run.log"
    tr = run_over_bus(make_profile("sine", duration_s=0.15), pace="sync", settings=rig.cfg,
                      values={"sensors.noise": True, "sensors.noise_seed": 4},
                      start_plant=False, log_path=log, echo=echo)
    dec = trace_from_log(log)
    assert tr.meta["complete"] and len(tr) == len(dec) == 150
    assert sorted(tr.columns) == sorted(dec.columns)
    for col in tr.columns:
        np.testing.assert_array_equal(tr[col], dec[col], err_msg=col)
    rows = tr.meta["bus_rows"]
    assert rows["sync_gaps"] == rows["duplicate_frames"] == 0
    assert set(rows["missing_frames"].values()) == {0}


def test_a_node_left_operational_without_sync_is_taken_over(rig):
    """A killed lockstep ECU leaves the node OPERATIONAL with no SYNC: not a reason to
    refuse; the ECU says it takes the node over and the run is normal."""
    rig.wbus.send(rig.frames.encode("NMT", {"NMT_Command": int(NMTCommand.START),
                                            "NMT_NodeId": 0x10}))
    until(lambda: rig.node.state == NMTState.OPERATIONAL, 1.0, "the node OPERATIONAL")
    said: list[str] = []
    tr = run_over_bus(make_profile("step", duration_s=0.1), pace="sync", settings=rig.cfg,
                      start_plant=False, announce=said.append)
    assert tr.meta["complete"] and len(tr) == 100
    assert any("OPERATIONAL" in s and "taking it over" in s for s in said), said


def test_a_foreign_sync_during_the_run_aborts_it_and_leaves_the_node_preoperational(rig):
    """A SYNC from another producer mid-run mixes both runs: the run fails with the
    partial trace kept, and the node is set PRE-OPERATIONAL (best effort)."""
    ecu, params = prepared(rig)
    other = rig.bus()

    def on_period(k: int) -> None:
        if k == 40:
            other.send(rig.frames.encode("SYNC", {"SYNC_Counter": 7}))

    with pytest.raises(BenchError, match=r"another ECU is driving node 0x10 \(SYNC from "
                                         r"another producer at t = 0\.0\d+ s"):
        ecu.run(make_profile("step", duration_s=0.3), params, pace=Pace.SYNC,
                on_period=on_period)
    assert 40 <= len(ecu.partial) <= 43 and ecu.partial.meta["complete"] is False
    until(lambda: rig.node.state == NMTState.PRE_OPERATIONAL, 1.0, "NMT pre-operational")


# -- item 13: the log ------------------------------------------------------------------------
class FullDisk:
    """A log file whose writes fail with ENOSPC after `ok` writes (a disk filling up)."""

    def __init__(self, real, ok: int) -> None:
        self.real, self.ok = real, ok

    def write(self, text: str) -> int:
        self.ok -= 1
        if self.ok < 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return self.real.write(text)

    def __getattr__(self, name: str):
        return getattr(self.real, name)


def test_an_unwritable_log_is_refused_before_the_plant_is_touched(rig):
    """`--log /dev/full`: unfixed, the receive thread died on the first flush and the run
    ended with "no actuator node answering"."""
    start = len(rig.msgs)
    with pytest.raises(BenchError, match=r"cannot write the log /dev/full: .*No space"):
        run_over_bus(make_profile("step", duration_s=0.05), pace="sync", settings=rig.cfg,
                     start_plant=False, log_path="/dev/full")
    assert not set(rig.ids_since(start)) & {NMT, SDO_RX}


def test_a_log_failing_during_set_up_is_reported_as_such(rig, tmp_path):
    """The disk fills during set-up: the receive thread keeps serving SDO, and the run
    stops with the log's error, not with a plant that does not answer."""
    ecu = rig.new_ecu(log_path=tmp_path / "r.log")
    ecu.log.writer.file = FullDisk(ecu.log.writer.file, 5)
    with pytest.raises(BenchError, match=r"cannot write the log .*r\.log: .*No space"):
        params = ecu.prepare(Pace.SYNC, {})
        ecu.run(make_profile("step", duration_s=0.1), params, pace=Pace.SYNC)


def test_a_log_failing_during_the_run_fails_it_with_the_partial_trace(rig, tmp_path):
    ecu, params = prepared(rig, log_path=tmp_path / "r.log")
    ecu.log.writer.file = FullDisk(ecu.log.writer.file, 600)
    with pytest.raises(BenchError, match=r"cannot write the log .*r\.log: .*No space.* at "
                                         r"t = 0\.\d+ s \(SYNC \d+\)"):
        ecu.run(make_profile("step", duration_s=0.4), params, pace=Pace.SYNC)
    part = ecu.partial
    assert 50 < len(part) < 400 and part.meta["complete"] is False
    assert np.isfinite(part["position_m"]).all()
    until(lambda: rig.node.state == NMTState.PRE_OPERATIONAL, 1.0, "NMT pre-operational")
