"""The loopback hub's bounds (item 7): queued bytes per client and in all,
acceptance filters, periodic tasks, connections, sessions that never start, backlog."""

from __future__ import annotations

import socket
import threading
import time

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_hub_events import (
    GOOD_MSG,
    OP_TEXT,
    WAIT_S,
    Closed,
    RawClient,
    good_pair,
    hub_state_bounded,
    running_hub,
    served,
)

from bench.bus import selecthub as hub_mod
from bench.bus.selecthub import SelectHub


def test_slow_readers_are_dropped_and_the_hub_stays_within_its_budget(monkeypatch):
    """20 clients that never read, a fast reader, 3000 frames: the fast reader gets every
    frame in order, the slow ones lose their connection, the queues stay in budget."""
    monkeypatch.setattr(hub_mod, "CLIENT_OUTBUF_MAX", 64 << 10, raising=False)
    monkeypatch.setattr(hub_mod, "TOTAL_OUTBUF_MAX", 256 << 10, raising=False)
    n = 3000
    with running_hub() as h, good_pair(h) as (a, b):
        slow = [RawClient(h.port, proto="can.json.v1", rcvbuf=4096) for _ in range(20)]
        got: list[int] = []

        def read() -> None:
            while len(got) < n:
                m = b.recv(WAIT_S)
                if m is None:
                    return
                got.append(int.from_bytes(m.data[:4], "little"))

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        for k in range(n):
            a.send(can.Message(arbitration_id=0x100, data=k.to_bytes(4, "little") + bytes(4),
                               is_extended_id=False))
        reader.join(30)
        assert got == list(range(n)), "the fast reader must get every frame, in order"
        assert served(a, b) == []
        h.assert_alive()
        assert len(h.hub.clients) == 2, "the 20 slow readers must be dropped"
        assert h.hub.stats["dropped_slow"] == 20
        assert h.hub.outbuf_peak <= 256 << 10
        hub_state_bounded(h.hub)
        for c in slow:                                # each sees its connection end
            with pytest.raises(Closed):
                while True:
                    c.recv_frame()


def test_a_burst_of_connections_waits_in_the_backlog():
    """200 connections while the hub is busy (not accepting): none may stall in SYN
    retries (a backlog of 16 made connects wait up to 1 s)."""
    hub = SelectHub()
    socks = []
    try:
        t0 = time.monotonic()
        for _ in range(200):
            s = socket.create_connection(("127.0.0.1", hub.port), timeout=0.5)
            socks.append(s)
        assert time.monotonic() - t0 < 5.0
    finally:
        for s in socks:
            s.close()
        hub.sel.close()
        hub.listener.close()


def test_connections_beyond_the_maximum_are_refused(monkeypatch):
    monkeypatch.setattr(hub_mod, "MAX_CLIENTS", 4, raising=False)
    with running_hub() as h, good_pair(h) as (a, b):
        RawClient(h.port)
        RawClient(h.port, request=False)
        with pytest.raises(AssertionError, match="HTTP/1.1 503"):
            RawClient(h.port)
        assert h.hub.stats["refused_full"] == 1
        assert served(a, b) == []


def test_a_session_that_never_starts_is_closed(monkeypatch):
    monkeypatch.setattr(hub_mod, "SESSION_TIMEOUT_S", 0.3, raising=False)
    with running_hub() as h, good_pair(h) as (a, b):
        idle = RawClient(h.port, request=False)
        silent = RawClient(h.port, upgrade=False, request=False)
        t0 = time.monotonic()
        assert idle.close_code() == 1008
        with pytest.raises(Closed):
            silent.recv_frame()
        assert time.monotonic() - t0 < 1.5
        assert served(a, b) == []                     # the good ones stay (they are older)
        assert len(h.hub.clients) == 2


def _periodic(c: RawClient, can_id: int, period: float, duration: float | None = None):
    c.send_event("periodic_start", {"msg": {**GOOD_MSG, "arbitration_id": can_id},
                                    "period": period, "duration": duration})


def test_periodic_tasks_per_client_are_capped():
    cap = hub_mod.MAX_PERIODIC_PER_CLIENT
    with running_hub() as h:
        c = RawClient(h.port)
        for i in range(cap + 1):
            _periodic(c, 0x400 + i, 10.0)
        assert c.sync()
        assert c.errors() == [f"periodic_start: at most {cap} periodic tasks per client"]
        _periodic(c, 0x400, 20.0)                     # replacing one is not one more
        c.send_event("periodic_stop", 0x401)
        _periodic(c, 0x500, 10.0)
        assert c.sync() and len(c.errors()) == 1
        assert len(h.hub.clients[max(h.hub.clients)].periodic) == cap
        hub_state_bounded(h.hub)


def test_periodic_frames_of_all_clients_are_capped_in_rate():
    budget = hub_mod.PERIODIC_RATE_MAX_HZ
    per_task = 1.0 / hub_mod.MIN_PERIOD_S
    fit = int(budget // per_task)
    with running_hub() as h:
        clients = [RawClient(h.port) for _ in range(fit // 8 + 1)]
        for i in range(fit + 1):
            _periodic(clients[i // 8], 0x100 + i, hub_mod.MIN_PERIOD_S, duration=5.0)
        assert all(c.sync() for c in clients)
        errors = [e for c in clients for e in c.errors()]
        assert errors == [f"periodic_start: the hub sends at most {budget:.0f} periodic "
                          "frames per second"]
        assert h.hub.periodic_rate == pytest.approx(fit * per_task)
        for c in clients:                             # leaving frees the budget
            c.close()
        deadline = time.monotonic() + WAIT_S
        while h.hub.clients and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not h.hub.clients and h.hub.periodic_rate == pytest.approx(0.0, abs=1e-6)


def test_periodic_duration_and_stop():
    with running_hub() as h, good_pair(h) as (a, b):
        c = RawClient(h.port)
        _periodic(c, 0x111, 0.01, duration=0.1)
        _periodic(c, 0x222, 0.01)
        time.sleep(0.3)
        c.send_event("periodic_stop", 0x222)
        assert c.sync() and c.errors() == []
        ids = [m.arbitration_id for m in served(a, b)]
        assert 5 <= ids.count(0x111) <= 12 and 15 <= ids.count(0x222) <= 32
        time.sleep(0.1)
        assert served(a, b) == []                     # both ended
        assert not h.hub.clients[max(h.hub.clients)].periodic


FILTER_BITS = st.sampled_from([0, 0x1, 0x7FF, 0x700, 0x7F0, 0x1FFFFFFF, 0x1FFFF800,
                               0xFFFFFFFF, 0x123, 0x10, 0x1ABCDEF0])
FILTERS = st.lists(st.builds(
    lambda i, m, e: {"can_id": i, "can_mask": m} | ({} if e is None else {"extended": e}),
    FILTER_BITS | st.integers(0, 0xFFFFFFFF), FILTER_BITS | st.integers(0, 0xFFFFFFFF),
    st.none() | st.booleans()), min_size=1, max_size=12)
FRAMES = st.lists(st.tuples(st.booleans(), st.integers(0, 0x1FFFFFFF) | FILTER_BITS),
                  min_size=1, max_size=30)


@pytest.fixture(scope="module")
def reference_bus():
    bus = can.Bus(interface="virtual", channel="hub-filter-test")
    yield bus
    bus.shutdown()


@settings(max_examples=60, derandomize=True, deadline=None, database=None)
@given(filters=FILTERS, frames=FRAMES)
def test_filters_match_as_python_can_does(reference_bus, filters, frames):
    reference_bus.set_filters(filters)                # python-can's own matching
    fs = hub_mod.FilterSet.parse(filters)
    for ext, can_id in frames:
        can_id &= 0x1FFFFFFF if ext else 0x7FF
        msg = can.Message(arbitration_id=can_id, is_extended_id=ext)
        assert fs.accepts(can_id, ext) == reference_bus._matches_filters(msg)
        assert fs.accepts(can_id, ext) == reference_bus._matches_filters(msg)   # remembered


def test_many_filters_cost_one_lookup_per_frame():
    """256 filters with 256 masks: each (id, extended) is matched in full once, after
    that a frame costs one dictionary look-up (20,000 filters made every run 13x slower)."""
    fs = hub_mod.FilterSet.parse([{"can_id": i, "can_mask": 0x7FF ^ i} for i in range(256)])
    ids = [(0x080, False), (0x190, False), (0x290, False), (0x390, False), (0x1ABC, True)]
    for _ in range(2000):
        for can_id, ext in ids:
            fs.accepts(can_id, ext)
    assert fs.evaluations == len(ids)
    with pytest.raises(hub_mod.BadEvent, match="257 filters, at most 256"):
        hub_mod.FilterSet.parse([{"can_id": 0, "can_mask": 0}] * 257)


def test_a_client_with_the_most_filters_gets_what_they_pass():
    filters = [{"can_id": 0x100 + i, "can_mask": 0x7FF, "extended": False} for i in range(255)]
    filters.append({"can_id": 0x1ABCDEF0, "can_mask": 0x1FFFFFFF, "extended": True})
    with running_hub() as h, good_pair(h) as (a, b):
        f = RawClient(h.port, config={"can_filters": filters})
        for can_id, ext in ((0x100, False), (0x0FF, False), (0x1FE, False), (0x1FF, False),
                            (0x1ABCDEF0, True), (0x100, True)):
            a.send(can.Message(arbitration_id=can_id, data=b"\x01", is_extended_id=ext))
        served(a, b)
        assert f.sync()
        got = [(op, p) for op, p in f.frames if op != OP_TEXT]
        ids = [int.from_bytes(p[9:13], "big") for _, p in got]     # type, timestamp, id
        assert ids == [0x100, 0x1FE, 0x1ABCDEF0]
