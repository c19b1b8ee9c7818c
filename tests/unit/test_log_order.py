"""A log the bench writes is in time order, as a real candump log (stamped at reception):
the ECU's log once had a received frame (stamped by the hub as it forwarded it) written
after an own frame the main thread sent and stamped later, while the received one waited
for the receive thread; under load `bench decode` counted such frames as out of order.
No frame is lost on the way."""

from __future__ import annotations

import time
from types import SimpleNamespace

import can
import pytest

from bench.bus.logs import read_frames
from bench.bus.logwrite import LOG_FORMATS, STEP_S, open_writer
from bench.ecu.link import EcuLink


def _stamps(path) -> list[tuple[float, int]]:
    return [(float(m.timestamp), m.arbitration_id) for m in read_frames(path)]


def test_ecu_log_never_goes_back_in_time(tmp_path):
    """A TPDO stamped by the hub, then an own SYNC sent (and logged) by the main thread
    before the receive thread records the TPDO: the log and the run's rows (the tap) get
    both, in non-decreasing time-stamp order."""
    bus = can.Bus(interface="virtual", channel="log-order")
    tapped: list[can.Message] = []
    try:
        link = EcuLink(bus, log_path=tmp_path / "ecu.log")
        link.tap = SimpleNamespace(append=tapped.append)  # type: ignore[assignment]
        now = time.time()
        # python-can's candump writer never goes before its first line's stamp: one first
        hb = can.Message(arbitration_id=0x700 + link.node_id, data=b"\x05",
                         is_extended_id=False, timestamp=now - 0.050)
        link._monitor(hb)
        tpdo = can.Message(arbitration_id=0x180 + link.node_id, data=bytes(8),
                           is_extended_id=False, timestamp=now - 0.010)
        link.send(can.Message(arbitration_id=0x080, data=b"\x01", is_extended_id=False))
        link._monitor(tpdo)                     # the receive thread gets to it late
        link.close()
    finally:
        bus.shutdown()
    got = _stamps(tmp_path / "ecu.log")
    assert [cid for _, cid in got] == [0x700 + link.node_id, 0x080, 0x180 + link.node_id]
    ts = [t for t, _ in got]
    assert ts == sorted(ts), f"log stamps go backwards: {ts}"
    tap_ts = [m.timestamp for m in tapped]
    assert len(tap_ts) == 3 and tap_ts == sorted(tap_ts), f"rows' stamps: {tap_ts}"


@pytest.mark.parametrize("suffix", list(LOG_FORMATS))
def test_writer_keeps_time_order(tmp_path, suffix):
    """Frames handed to the writer with stamps out of order (a wall clock stepped back)
    are all written, in the order given, with stamps that never go backwards."""
    path = tmp_path / f"w{suffix}"
    writer = open_writer(path)
    t0 = 1_700_000_000.0
    given = [(t0 + 1.0, 0x181), (t0 + 3.0, 0x281), (t0 + 2.0, 0x381), (t0 + 2.5, 0x701),
             (t0 + 4.0, 0x080)]
    for ts, cid in given:
        writer.on_message_received(can.Message(timestamp=ts, arbitration_id=cid,
                                               data=bytes(2), is_extended_id=False))
    writer.stop()
    got = _stamps(path)
    assert [cid for _, cid in got] == [cid for _, cid in given]
    ts = [t for t, _ in got]
    assert ts == sorted(ts), f"{suffix} stamps go backwards: {ts}"
    assert len(set(ts)) == len(ts)          # a late frame never shares the stamp before it
    assert ts[3] - ts[0] == pytest.approx(2.0 + 2 * STEP_S, abs=1e-6)
    assert ts[4] - ts[0] == pytest.approx(3.0, abs=1e-6)
