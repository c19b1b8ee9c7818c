"""`ema_contract.node.CanopenNode`, the node base of the plant, `indie_plant` and the test
double: driven frame by frame (`handle`, then `timers`) with a fake wall clock on a
virtual bus, through the test double `MinimalNode` (no physics: a fake one)."""

from __future__ import annotations

import uuid

import can
import pytest
from minimal_node import MinimalNode

from ema_contract.frames import Frames
from ema_contract.node import CanopenNode, FrameCounters, cia301_od
from ema_contract.states import NMTState

HB = 0x710


class FakePhysics:
    period_s = 0.001

    def __init__(self) -> None:
        self.steps: list[float] = []
        self.resets = 0

    def reset(self) -> None:
        self.resets += 1

    def step(self, demand_a: float) -> None:
        self.steps.append(demand_a)

    def sample(self) -> tuple[dict[str, float], int]:
        return ({"MotorCurrent": 0.5, "EncoderAngle": 10, "EncoderSpeed": 1.0,
                 "LvdtPosition": 0.001, "WindingTemperature": 300.0, "LoadForce": 10.0}, 0)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def rig():
    chan = f"nb-{uuid.uuid4().hex}"
    nbus = can.Bus(interface="virtual", channel=chan)
    bus = can.Bus(interface="virtual", channel=chan)
    clock = Clock()
    node = MinimalNode(nbus, FakePhysics(), clock=clock)
    node.boot()
    yield node, bus, clock
    nbus.shutdown()
    bus.shutdown()


def received(bus: can.BusABC) -> list[can.Message]:
    out = []
    while (m := bus.recv(timeout=0.0)) is not None:
        out.append(m)
    return out


def frame(can_id: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=False)


def start(node: MinimalNode, bus: can.BusABC) -> None:
    node.handle(frame(0x000, bytes([1, node.node_id])))
    assert node.state == NMTState.OPERATIONAL
    received(bus)


def test_a_sync_of_two_or_more_bytes_is_a_bad_frame_and_moves_nothing(rig):
    """CiA 301: a SYNC carries 0 or 1 byte. One of 3 bytes is counted as bad and
    triggers no TPDO and no step (the test double used to answer it as a SYNC)."""
    node, bus, _ = rig
    start(node, bus)
    node.handle(frame(0x080, bytes([1, 2, 3])))
    assert received(bus) == [] and node.physics.steps == []
    assert node.counters.bad_frames == 1
    node.handle(frame(0x080, bytes([1])))
    assert [m.arbitration_id for m in received(bus)] == [0x190, 0x290, 0x390]
    assert node.physics.steps == [0.0]


def test_a_heartbeat_behind_its_time_is_one_frame_not_a_burst(rig):
    """A loop stalled for several heartbeat periods sends one heartbeat, then the next
    one period later (the test double used to send two back to back)."""
    node, bus, clock = rig
    received(bus)
    clock.t += 5 * node.heartbeat_ms / 1000.0
    node.timers()
    node.timers()
    assert [m.arbitration_id for m in received(bus)] == [HB]
    clock.t += node.heartbeat_ms / 1000.0
    node.timers()
    assert [m.arbitration_id for m in received(bus)] == [HB]


def test_nmt_reset_node_resets_the_application_then_boots(rig):
    node, bus, _ = rig
    start(node, bus)
    node.handle(frame(0x000, bytes([0x81, 0])))
    assert node.physics.resets == 1 and node.state == NMTState.PRE_OPERATIONAL
    boot = received(bus)
    assert [(m.arbitration_id, bytes(m.data)) for m in boot] == [(HB, b"\x00")]


def test_frames_the_node_cannot_use_are_counted_never_raised(rig):
    node, bus, _ = rig
    received(bus)                                      # the boot-up
    node.handle(can.Message(arbitration_id=0x123456, data=b"", is_extended_id=True))
    node.handle(frame(0x7FF, b"\x01"))                 # not in the DBC
    node.handle(frame(0x000, b"\x01"))                 # NMT of the wrong length
    node.handle(frame(node.sdo_cob, b"\x40\x00"))      # SDO of the wrong length
    c = node.counters
    assert (c.frames_received, c.unknown_frames, c.bad_frames) == (4, 2, 2)
    assert received(bus) == []


def test_drain_serves_every_frame_already_received_without_waiting(rig):
    node, bus, _ = rig
    for _ in range(5):
        bus.send(frame(0x7FF, b"\x01"))
    node.drain()
    assert node.counters.frames_received == 5


def test_a_bare_base_node_boots_and_serves_the_heartbeat_objects():
    """The base alone: the heartbeat producer time 0x1017 is served (SDO hooks), and a
    hook-less node ignores SYNC."""
    chan = f"nb-{uuid.uuid4().hex}"
    nbus = can.Bus(interface="virtual", channel=chan)
    try:
        frames = Frames()
        node = CanopenNode(nbus, frames, cia301_od(frames.node_id), clock=Clock())
        assert isinstance(node.counters, FrameCounters)
        od = node.od[0x1017]
        node._sdo_write(0x1017, 0, od, od.encode_raw(250))
        assert node.heartbeat_ms == 250 and node._sdo_read(0x1017, 0, od) == 250
        node.handle(frame(0x080, b""))
        assert node.counters.bad_frames == 0
    finally:
        nbus.shutdown()
