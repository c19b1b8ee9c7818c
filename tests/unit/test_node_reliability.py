"""Reliability of the plant node, in-process and deterministic: frames are fed to
`PlantNode.handle()` (then `timers()`, as the node's loop does) with a fake wall clock,
and what the node sends is kept by a recording bus.

- the heartbeat consumer (0x1016) runs on the SYNC time base in lockstep: a late ECU
  heartbeat (a stalled thread, a loaded machine) no longer latches a command timeout;
  more SYNC periods than the consumer time without a heartbeat does;
- on a consumer timeout the node follows the error behaviour object 0x1029 (default 0:
  OPERATIONAL -> PRE-OPERATIONAL), EMCY 0x8130 once;
- EMCY inhibit time 0x1015: a flood of bad RPDOs gives one EMCY and one log line per
  inhibit time, repeats counted, nothing lost.
"""

from __future__ import annotations

import logging
import re

import can
import pytest
from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.frames import load_od
from ema_contract.states import NMTCommand, NMTState, Pace, StatusWord
from plant_rt.node import PlantNode
from plant_rt.params import PlantParams

TIMEOUT = int(StatusWord.COMMAND_TIMEOUT)
ENABLED = int(StatusWord.ENABLED)


class RecordingBus(can.BusABC):
    """A bus that keeps what the node sends and receives nothing (frames are fed)."""

    def __init__(self) -> None:
        super().__init__(channel="recording")
        self.sent: list[can.Message] = []

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.sent.append(msg)

    def _recv_internal(self, timeout):
        return None, False


class Clock:
    """A wall clock that moves only when told (s)."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


_BUSES: list[RecordingBus] = []


@pytest.fixture(autouse=True)
def _shut_buses():
    yield
    while _BUSES:
        _BUSES.pop().shutdown()


class Feeder:
    """A PlantNode driven frame by frame, as its loop would: handle(), then timers()."""

    def __init__(self, pace: Pace) -> None:
        self.bus = RecordingBus()
        _BUSES.append(self.bus)
        self.clock = Clock()
        self.node = PlantNode(self.bus, PlantParams(), pace=pace, clock=self.clock)
        self.f = self.node.frames
        self.node.boot()
        self.counter = 0

    def feed(self, msg: can.Message) -> None:
        self.node.handle(msg)
        self.node.timers()

    def send(self, name: str, values: dict, strict: bool = True) -> None:
        enc = self.f.encode if strict else self.f.encode_unchecked
        self.feed(enc(name, values))

    def nmt(self, cmd: NMTCommand) -> None:
        self.send("NMT", {"NMT_Command": int(cmd), "NMT_NodeId": self.node.node_id})

    def heartbeat(self) -> None:
        self.send("ECU_Heartbeat", {"ECU_NMTState": int(NMTState.OPERATIONAL)})

    def rpdo(self, demand_a: float, control: int = 1) -> None:
        self.send("EMA_RPDO1", {"CurrentDemand": demand_a, "ControlWord": control},
                  strict=False)

    def sync(self) -> int | None:
        """One SYNC; the status word of the TPDO1 it triggered (None: no TPDO1)."""
        self.counter = self.counter % 240 + 1
        start = len(self.bus.sent)
        self.send("SYNC", {"SYNC_Counter": self.counter})
        tp1 = [m for m in self.bus.sent[start:] if m.arbitration_id == self.f.cob["EMA_TPDO1"]]
        return int(self.f.decode(tp1[0])[1]["StatusWord"]) if tp1 else None

    def emcy(self) -> list[dict]:
        out = []
        for i, m in enumerate(self.bus.sent):
            if m.arbitration_id == self.f.cob["EMA_EMCY"]:
                sig = self.f.decode(m)[1]
                out.append({**sig, "at": i, "name": self.f.label(
                    "EMA_EMCY", "EMCY_ErrorCode", sig["EMCY_ErrorCode"])})
        return out

    def syncs_before(self, at: int) -> int:
        """TPDO1 frames (SYNCs answered) among the first `at` frames the node sent."""
        cob = self.f.cob["EMA_TPDO1"]
        return sum(1 for m in self.bus.sent[:at] if m.arbitration_id == cob)

    def names(self) -> list[str]:
        return [e["name"] for e in self.emcy()]

    def write(self, index: int, sub: int, raw: int) -> None:
        """An SDO download as the node's SDO server performs it (callbacks, checks)."""
        od = self.node.od[index] if sub == 0 and not hasattr(self.node.od[index],
                                                                "subindices") \
            else self.node.od[index][sub]
        self.node.local.set_data(index, sub, od.encode_raw(raw), check_writable=True)

    def read(self, index: int, sub: int) -> int:
        od = self.node.od[index] if not hasattr(self.node.od[index], "subindices") \
            else self.node.od[index][sub]
        return od.decode_raw(self.node.local.get_data(index, sub, check_readable=True))


# -- heartbeat consumer in lockstep -----------------------------------------------------------
def test_lockstep_late_ecu_heartbeat_does_not_latch_a_command_timeout():
    """The failure this guards against: the ECU's heartbeats arrive every 100 SYNCs, but its thread
    stalls 400 ms of wall time between two SYNCs. Lockstep: nothing was lost."""
    fd = Feeder(Pace.SYNC)
    fd.nmt(NMTCommand.START)
    fd.heartbeat()
    fd.rpdo(1.0)
    words = []
    for k in range(1, 701):
        if k % 100 == 0:
            fd.heartbeat()
        fd.clock.t += 0.4 if k == 350 else 1e-3       # a stalled thread at SYNC 350
        words.append(fd.sync())
        fd.rpdo(1.0)
    assert all(w is not None and not w & TIMEOUT and w & ENABLED for w in words[1:])
    assert fd.node.counters.heartbeat_timeouts == 0
    assert "heartbeat_lost" not in fd.names()
    assert fd.node.state == NMTState.OPERATIONAL
    assert fd.node.applied_a == 1.0
    assert fd.node.counters.cycles == 700


def test_lockstep_no_ecu_heartbeat_for_more_than_the_consumer_time_in_syncs_latches():
    """0x1016 = 300 ms, SYNC period 1 ms: the 301st SYNC period without an ECU heartbeat
    latches the timeout, though the wall clock never moves; 0x1029 = 0 (default): the node
    leaves OPERATIONAL, demand 0, one EMCY 0x8130, no TPDO for that SYNC."""
    fd = Feeder(Pace.SYNC)
    fd.nmt(NMTCommand.START)
    fd.heartbeat()
    fd.rpdo(2.0)
    for _ in range(300):
        w = fd.sync()
        assert w is not None and not w & TIMEOUT
        fd.rpdo(2.0)
    assert fd.node.applied_a == 2.0 and fd.names() == []
    assert fd.sync() is None                            # SYNC period 301: timeout
    node = fd.node
    assert node.counters.heartbeat_timeouts == 1
    assert node.state == NMTState.PRE_OPERATIONAL
    assert node.applied_a == 0.0
    em = fd.emcy()
    assert [e["name"] for e in em] == ["heartbeat_lost"]
    assert em[0]["EMCY_StatusWord"] & TIMEOUT and not em[0]["EMCY_StatusWord"] & ENABLED
    cycles = node.counters.cycles
    for _ in range(50):                                  # the ECU keeps sending SYNCs
        fd.rpdo(2.0)
        assert fd.sync() is None
    assert node.counters.cycles == cycles == 300          # the plant does not move
    assert fd.names() == ["heartbeat_lost"]               # sent once
    assert node.counters.heartbeat_timeouts == 1


def test_lockstep_consumer_ignores_the_wall_clock_in_pre_operational_too():
    """No SYNC, no time: an ECU that stalls (or dies) in lockstep leaves the node as it is,
    which is safe, since the plant only moves at a SYNC."""
    fd = Feeder(Pace.SYNC)
    fd.nmt(NMTCommand.START)
    fd.heartbeat()
    fd.rpdo(1.0)
    fd.sync()
    fd.clock.t += 60.0
    fd.node.timers()
    assert fd.node.counters.heartbeat_timeouts == 0
    assert fd.node.state == NMTState.OPERATIONAL and fd.names() == []


# -- heartbeat consumer in real time, error behaviour 0x1029 ---------------------------------
def test_realtime_ecu_heartbeat_lost_node_leaves_operational_with_one_emcy():
    fd = Feeder(Pace.REALTIME)
    fd.nmt(NMTCommand.START)
    fd.heartbeat()
    fd.rpdo(3.0)
    fd.sync()
    assert fd.node.applied_a == 3.0
    fd.clock.t += 0.299
    fd.node.timers()
    assert fd.node.state == NMTState.OPERATIONAL and fd.names() == []
    fd.clock.t += 0.002
    fd.node.timers()
    node = fd.node
    assert node.state == NMTState.PRE_OPERATIONAL
    assert node.applied_a == 0.0 and node.counters.heartbeat_timeouts == 1
    em = fd.emcy()
    assert [e["name"] for e in em] == ["heartbeat_lost"]
    assert em[0]["EMCY_StatusWord"] & TIMEOUT and not em[0]["EMCY_StatusWord"] & ENABLED
    for _ in range(20):
        fd.clock.t += 0.1
        node.timers()
    assert fd.names() == ["heartbeat_lost"] and node.counters.heartbeat_timeouts == 1
    # the ECU comes back: start again, a fault-reset edge clears the latch
    fd.heartbeat()
    fd.nmt(NMTCommand.START)
    fd.rpdo(1.5, 0x81)
    assert fd.sync() & TIMEOUT == 0
    assert node.applied_a == 1.5


@pytest.mark.parametrize("behaviour, state", [(1, NMTState.OPERATIONAL),
                                              (2, NMTState.STOPPED)])
def test_error_behaviour_object_selects_the_state_after_a_timeout(behaviour, state):
    fd = Feeder(Pace.SYNC)
    assert fd.read(0x1029, 1) == 0
    fd.write(0x1029, 1, behaviour)
    assert fd.read(0x1029, 1) == behaviour
    fd.nmt(NMTCommand.START)
    fd.heartbeat()
    fd.rpdo(2.0)
    words = [fd.sync() for _ in range(302)]
    assert fd.node.state == state
    assert fd.node.applied_a == 0.0 and fd.names() == ["heartbeat_lost"]
    if behaviour == 1:      # drive stays OPERATIONAL, demand forced to 0, status bit 4
        assert words[-1] & TIMEOUT and not words[-1] & ENABLED


def test_error_behaviour_refuses_unknown_values_and_resets_with_the_node():
    fd = Feeder(Pace.SYNC)
    with pytest.raises(SdoAbortedError) as e:
        fd.write(0x1029, 1, 3)
    assert e.value.code == 0x06090030
    fd.write(0x1029, 1, 1)
    fd.nmt(NMTCommand.RESET_NODE)
    assert fd.read(0x1029, 1) == 0


# -- EMCY inhibit time 0x1015 -----------------------------------------------------------------
def _flood(fd: Feeder, pairs: int, dt_s: float) -> None:
    valid = fd.f.encode("EMA_RPDO1", {"CurrentDemand": 1.0, "ControlWord": 1})
    short = can.Message(arbitration_id=fd.f.cob["EMA_RPDO1"], data=b"\x00\x00",
                        is_extended_id=False)
    for _ in range(pairs):
        fd.feed(valid)
        fd.clock.t += dt_s
        fd.feed(short)
        fd.clock.t += dt_s


def test_emcy_inhibit_time_object_defaults_to_100_ms_and_is_writable():
    od = load_od()
    assert od[0x1015].default == 1000                   # 100 us units
    fd = Feeder(Pace.REALTIME)
    assert fd.read(0x1015, 0) == 1000
    fd.write(0x1015, 0, 50)
    assert fd.read(0x1015, 0) == 50
    fd.nmt(NMTCommand.RESET_NODE)
    assert fd.read(0x1015, 0) == 1000


def test_emcy_storm_of_alternating_valid_and_short_rpdos_is_rate_limited(caplog):
    """50,000 frames in 0.5 s of wall time, half of them short RPDOs: one EMCY 0x8210 and
    one log line per key per 100 ms, every bad frame counted, the last state sent."""
    caplog.set_level(logging.DEBUG, logger="plant_rt.node")
    fd = Feeder(Pace.REALTIME)
    fd.nmt(NMTCommand.START)
    caplog.clear()
    _flood(fd, 25_000, 10e-6)
    fd.clock.t += 0.2
    fd.node.timers()
    c = fd.node.counters
    names = fd.names()
    print(f"EMCY frames: {len(names)}, log lines: {len(caplog.records)}")
    assert c.bad_frames == 25_000
    assert set(names) == {"pdo_length"}
    assert 5 <= len(names) <= 7                     # 0.5 s / 100 ms, plus the last state
    assert c.emcy_sent == len(names)
    assert c.emcy_sent + c.emcy_suppressed == 25_000
    assert len(caplog.records) <= 2 * 7
    # the suppressed repeats are reported in the log lines, all of them
    counted = sum(int(m.group(1)) for r in caplog.records
                  if (m := re.search(r"^EMCY .*, (\d+) repeats suppressed", r.getMessage())))
    assert counted == c.emcy_suppressed
    assert fd.node.state == NMTState.OPERATIONAL


def test_emcy_inhibit_zero_disables_it():
    fd = Feeder(Pace.REALTIME)
    fd.write(0x1015, 0, 0)
    fd.nmt(NMTCommand.START)
    _flood(fd, 100, 10e-6)
    assert fd.names() == ["pdo_length"] * 100


def test_lockstep_emcy_inhibit_counts_sync_periods_and_is_deterministic():
    """Lockstep: the inhibit time runs on the SYNC time base while OPERATIONAL (the EMCYs
    fall on the same SYNCs whatever the wall clock does)."""
    runs = []
    for jitter in (0.0, 0.05):
        fd = Feeder(Pace.SYNC)
        fd.nmt(NMTCommand.START)
        fd.heartbeat()
        for k in range(250):
            if k % 100 == 0:
                fd.heartbeat()
            _flood(fd, 40, jitter * (k % 3))
            fd.sync()
        runs.append([(fd.syncs_before(e["at"]), e["EMCY_Cycle"], e["name"])
                     for e in fd.emcy()])
        assert fd.node.counters.bad_frames == 10_000
    assert runs[0] == runs[1]
    assert [n for _, _, n in runs[0]] == ["pdo_length"] * 3
    assert [s for s, _, _ in runs[0]] == [0, 100, 200]     # sent at these SYNCs
    assert [c for _, c, _ in runs[0]] == [0, 99, 199]      # the latest repeat's cycle


def test_distinct_conditions_during_the_inhibit_time_are_sent_after_it():
    fd = Feeder(Pace.SYNC)
    fd.nmt(NMTCommand.START)
    fd.heartbeat()
    fd.sync()
    fd.feed(can.Message(arbitration_id=0x210, data=b"\x01", is_extended_id=False))
    fd.rpdo(float("nan"))                              # demand invalid: status bit 5
    fd.sync()
    assert fd.names() == ["pdo_length"]                # demand_invalid waits
    for k in range(400):
        if k % 100 == 0:
            fd.heartbeat()
        fd.rpdo(0.5)
        fd.sync()
    em = fd.emcy()
    assert [e["name"] for e in em] == ["pdo_length", "demand_invalid", "no_error"]
    # pdo_length after SYNC 1; demand_invalid arose at the step of SYNC 2 (its cycle), is
    # sent when the inhibit time ends, 100 SYNC periods after the first EMCY
    assert [fd.syncs_before(e["at"]) for e in em[:2]] == [1, 101]
    assert [e["EMCY_Cycle"] for e in em[:2]] == [1, 2]
    assert fd.node.counters.emcy_suppressed == 0


def test_a_reset_sends_the_waiting_emcys_before_the_boot_up():
    """EMCYs waiting for the inhibit time belong to the session a reset ends: they go out
    before the boot-up frame, never into the next session (the next run's log)."""
    fd = Feeder(Pace.REALTIME)
    fd.nmt(NMTCommand.START)
    _flood(fd, 3, 1e-3)                                # pdo_length sent, 2 repeats wait
    assert fd.names() == ["pdo_length"]
    fd.nmt(NMTCommand.RESET_NODE)
    boot = [i for i, m in enumerate(fd.bus.sent) if m.arbitration_id == 0x710
            and m.data[0] == 0]
    em = fd.emcy()
    assert [e["name"] for e in em] == ["pdo_length"] * 2
    assert em[1]["at"] < boot[-1]
    fd.clock.t += 1.0
    fd.node.timers()
    assert len(fd.emcy()) == 2                          # nothing left for the new session
    _flood(fd, 1, 1e-3)                                 # the new session is not throttled
    assert len(fd.emcy()) == 3


def test_log_limiter_one_line_per_window_with_the_count(caplog):
    from plant_rt.node import LogLimiter
    lim = LogLimiter(logging.getLogger("t.limiter"), 0.1)
    caplog.set_level(logging.INFO, logger="t.limiter")
    for k in range(1000):                              # 1000 lines in 0.5 s
        try:
            raise ValueError(k)
        except ValueError:
            lim.log(k * 5e-4, logging.INFO, "bad %d", k, exc_info=True)
        lim.flush(k * 5e-4)
    lim.flush(1.0)
    msgs = [r.getMessage() for r in caplog.records]
    assert len(msgs) == 6                               # at 0, 0.1, ..., 0.4 and the last
    assert msgs[0] == "bad 0" and msgs[-1] == "bad 999 [198 similar lines suppressed]"
    assert 6 + sum(int(m.split("[")[1].split()[0]) for m in msgs[1:]) == 1000
    assert str(caplog.records[-1].exc_info[1]) == "999"  # the traceback of that line
