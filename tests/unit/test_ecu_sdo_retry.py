"""The ECU's SDO set-up on a loaded machine: an answer that comes after the SDO timeout
(here: held back by the server until the next transfer) is waited out by starting the
transfer again, and is never taken for the answer to the next request."""

from __future__ import annotations

import struct
import uuid

import can
import canopen
import pytest
from canopen.network import MessageListener

from bench import BenchError
from bench.ecu import Ecu
from bench.ecu.sdoclient import MatchingSdoClient, expected_answer
from ema_contract.frames import load_od
from ema_contract.transport import close_bus


class LateNetwork(canopen.Network):
    """The server's network: the first answer about object `late` is held back and sent
    just before the server's next answer about another object (a late frame)."""

    def __init__(self, bus: can.BusABC, late: tuple[int, int]) -> None:
        super().__init__(bus)
        self.late = late
        self.held: bytes | None = None
        self.done = False

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        data = bytes(data)
        mux = struct.unpack_from("<HB", data, 1)
        if can_id & 0x780 == 0x580 and not self.done and mux == self.late:
            self.held, self.done = data, True
            return
        if self.held is not None and mux != self.late:
            held, self.held = self.held, None
            super().send_message(can_id, held)
        super().send_message(can_id, data, remote)


@pytest.fixture
def pair():
    """An ECU and a canopen LocalNode (the EDS's objects) on a virtual bus; the node's
    first answer about 0x1016 sub 1 comes late."""
    chan = f"sdo-{uuid.uuid4().hex}"
    ecu_bus = can.Bus(interface="virtual", channel=chan)
    node_bus = can.Bus(interface="virtual", channel=chan)
    net = LateNetwork(node_bus, (0x1016, 1))
    node = canopen.LocalNode(0x10, load_od(0x10))
    net.add_node(node)
    net.notifier = can.Notifier(node_bus, [MessageListener(net)], 0.02)
    ecu = Ecu(ecu_bus)
    try:
        yield ecu, net
    finally:
        ecu.close()
        net.notifier.stop(1.0)
        close_bus(ecu_bus)
        close_bus(node_bus)


def test_a_late_answer_is_waited_out_and_not_taken_for_the_next(pair):
    ecu, net = pair
    assert isinstance(ecu.remote.sdo, MatchingSdoClient)
    ecu.sdo_write((0x1016, 1), 0)        # the first answer is late: started again
    assert net.done and ecu.sdo_retries == 1
    # the late answer ("written") comes just before the refusal of the next write: it
    # must not be taken for that write's answer (canopen checks no download's object)
    with pytest.raises(BenchError, match="refused"):
        ecu.sdo_write(0x1000, 5)          # device type: read-only (abort 0x06010002)
    assert ecu.remote.sdo.stray >= 1
    assert ecu.sdo_read((0x1018, 2)) == int(load_od(0x10)[0x1018][2].default)


def test_answers_are_matched_to_their_request():
    up = bytes([0x40, 0x03, 0x20, 0x08, 0, 0, 0, 0])       # initiate upload 0x2003 sub 8
    mask, value, mux = expected_answer(up, None)
    assert (mask, value, mux) == (0xE0, 0x40, bytes([0x03, 0x20, 0x08]))
    seg = bytes([0x70, 0, 0, 0, 0, 0, 0, 0])                  # upload segment, toggle 1
    assert expected_answer(seg, mux)[:2] == (0xF0, 0x10)
    down = bytes([0x23, 0x16, 0x10, 0x01, 0, 0, 0, 0])       # expedited download 0x1016/1
    assert expected_answer(down, None) == (0xE0, 0x60, bytes([0x16, 0x10, 0x01]))
    dseg = bytes([0x00, 1, 2, 3, 4, 5, 6, 7])                 # download segment, toggle 0
    assert expected_answer(dseg, mux)[:2] == (0xF0, 0x20)
