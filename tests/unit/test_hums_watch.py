"""`bench hums watch`'s loop (`bench.hums.live.watch`): when is a run over?"""

from __future__ import annotations

import time

import can

from bench.hums.live import watch

SYNC = 0x080


class FakeHums:
    """Stands in for LiveHums: records SYNCs as LiveHums does; the first one is slow (the
    compiled monitor loads), as in a fresh watcher process."""

    def __init__(self, first_delay_s: float) -> None:
        self.last_sync = self.last_sync_stamp = None
        self.delay = first_delay_s
        self.syncs = 0

    def feed(self, msg: can.Message) -> list[int]:
        if msg.arbitration_id != SYNC:
            return []
        self.last_sync, self.last_sync_stamp = time.monotonic(), msg.timestamp
        self.syncs += 1
        if self.syncs == 1:
            time.sleep(self.delay)
        return [self.syncs] if self.syncs % 100 == 0 else []

    def finish(self) -> list[int]:
        return []


class ListBus:
    def __init__(self, msgs: list[can.Message]) -> None:
        self.msgs = list(msgs)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if self.msgs:
            return self.msgs.pop(0)
        time.sleep(min(timeout or 0.0, 0.01))
        return None


def frames(n_sync: int, t0: float = 1000.0) -> list[can.Message]:
    """A lockstep run on the bus's clock: a SYNC and a TPDO every 1 ms, then heartbeats
    for 1 s after the last SYNC."""
    out = []
    for k in range(n_sync):
        out.append(can.Message(timestamp=t0 + k * 1e-3, arbitration_id=SYNC, data=b"\x01",
                               is_extended_id=False))
        out.append(can.Message(timestamp=t0 + k * 1e-3 + 2e-4, arbitration_id=0x190,
                               data=bytes(6), is_extended_id=False))
    t_end = t0 + n_sync * 1e-3
    for j in range(10):
        out.append(can.Message(timestamp=t_end + 0.1 * (j + 1), arbitration_id=0x710,
                               data=b"\x05", is_extended_id=False))
    return out


def test_the_watchers_own_work_is_not_idle_time():
    """A slow first period (0.3 s > idle 0.2 s) must not end the watch while the run's
    frames are still queued. Before the fix the idle clock ran on the wall clock during
    the watcher's own work: it stopped after the first SYNC ("0 command periods")."""
    hums = FakeHums(first_delay_s=0.3)
    n = watch(ListBus(frames(500)), hums, lambda r: None, idle_s=0.2)
    assert hums.syncs == 500
    assert n == 5


def test_the_run_ends_after_idle_on_the_bus_clock():
    """Heartbeats keep coming after the run: the watch ends at the first frame stamped
    more than idle_s after the last SYNC, without waiting on the wall clock."""
    hums = FakeHums(first_delay_s=0.0)
    bus = ListBus(frames(200))
    t0 = time.monotonic()
    watch(bus, hums, lambda r: None, idle_s=0.25)
    assert hums.syncs == 200
    assert len(bus.msgs) == 7          # the 3rd heartbeat (0.3 s after) ended it
    assert time.monotonic() - t0 < 0.25
