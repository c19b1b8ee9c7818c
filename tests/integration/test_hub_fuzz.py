"""Fuzz test of the loopback hub's WebSocket frame parser and event parser (hypothesis,
derandomized): whatever one client sends, the hub never raises, its state stays within
its limits, nothing invalid reaches the bus (python-can's own `Message` check), and a
good pair of python-can-remote clients is still served after every example."""

from __future__ import annotations

import struct

import can
from can.util import CAN_FD_DLC
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_hub_events import (
    OP_BINARY,
    OP_TEXT,
    Closed,
    RawClient,
    hub_state_bounded,
    open_remote,
    running_hub,
    served,
)

from ema_contract import transport as T

EXAMPLES = 250
FLAG_BITS = {"is_extended_id": 0x1, "is_remote_frame": 0x2, "is_error_frame": 0x4,
             "is_fd": 0x8, "bitrate_switch": 0x10, "error_state_indicator": 0x20}

TEXT = st.text(st.characters(blacklist_categories=("Cs",)), max_size=12)
SPECIAL_INTS = st.sampled_from([0, 1, -1, 7, 8, 9, 64, 65, 255, 256, 300, 0x7FF, 0x800,
                                0x1FFFFFFF, 0x20000000, 2**32, 2**40, 2**63, 10**8, 10**30])
NUMBERS = (SPECIAL_INTS | st.integers() | st.floats(allow_nan=True, allow_infinity=True)
           | st.sampled_from([0.0, 1e-4, 1e-3, 0.01, -1.0]))
JSON = st.recursive(st.none() | st.booleans() | NUMBERS | TEXT,
                    lambda kids: st.lists(kids, max_size=4)
                    | st.dictionaries(TEXT, kids, max_size=4), max_leaves=12)


def maybe(good):
    """Mostly a plausible value, sometimes any JSON at all."""
    return st.one_of(good, good, JSON)


@st.composite
def valid_message(draw) -> dict:
    """A message python-can-remote's client could send (classic or FD, data or remote)."""
    ext, fd = draw(st.booleans()), draw(st.booleans())
    can_id = draw(st.integers(0, 0x1FFFFFFF if ext else 0x7FF))
    if fd:
        n = draw(st.sampled_from(CAN_FD_DLC))
        remote = False
    else:
        n, remote = draw(st.integers(0, 8)), draw(st.booleans())
    data = [] if remote else draw(st.lists(st.integers(0, 255), min_size=n, max_size=n))
    return {"timestamp": 0.0, "arbitration_id": can_id, "is_extended_id": ext,
            "is_remote_frame": remote, "is_error_frame": False, "is_fd": fd,
            "bitrate_switch": fd and draw(st.booleans()), "error_state_indicator": False,
            "dlc": n, "data": data}


@st.composite
def one_field_off(draw, good) -> dict:
    """A valid message with one field changed, dropped or added."""
    m = dict(draw(good))
    key = draw(st.sampled_from(sorted(m) + ["extra"]))
    if draw(st.booleans()):
        m.pop(key, None)
    else:
        m[key] = draw(SPECIAL_INTS | JSON)
    return m


FREE_MESSAGE = st.fixed_dictionaries({}, optional={
    "arbitration_id": maybe(SPECIAL_INTS | st.integers(0, 0x1FFFFFFF)),
    "is_extended_id": maybe(st.booleans()), "is_remote_frame": maybe(st.booleans()),
    "is_error_frame": maybe(st.booleans()), "is_fd": maybe(st.booleans()),
    "bitrate_switch": maybe(st.booleans()), "error_state_indicator": maybe(st.booleans()),
    "dlc": maybe(st.integers(0, 70)), "timestamp": maybe(st.floats(0, 1e9)),
    "data": maybe(st.lists(st.integers(0, 255) | SPECIAL_INTS, max_size=70))})
MESSAGE = st.one_of(valid_message(), one_field_off(valid_message()), FREE_MESSAGE)


def binary_of(m: dict) -> tuple:
    flags = sum(bit for key, bit in FLAG_BITS.items() if m[key])
    return ("binary", 1, m["arbitration_id"], m["dlc"], flags, bytes(m["data"]))


FILTER = st.fixed_dictionaries({}, optional={
    "can_id": maybe(SPECIAL_INTS), "can_mask": maybe(SPECIAL_INTS),
    "extended": maybe(st.booleans())})
REQUEST = st.fixed_dictionaries({}, optional={"config": maybe(st.fixed_dictionaries({}, optional={
    "can_filters": maybe(st.none() | st.lists(FILTER, max_size=4)),
    "receive_own_messages": maybe(st.booleans()), "bitrate": JSON}))})
PERIODIC = st.fixed_dictionaries({}, optional={
    "msg": maybe(MESSAGE), "period": maybe(st.sampled_from([0, 1e-4, 1e-3, 0.05, 1.0])),
    "duration": maybe(st.none() | st.sampled_from([0, 0.01, -1.0]))})
EVENT = st.one_of(
    st.tuples(st.just("message"), maybe(MESSAGE)),
    st.tuples(st.just("periodic_start"), maybe(PERIODIC)),
    st.tuples(st.just("periodic_stop"), maybe(SPECIAL_INTS)),
    st.tuples(st.just("bus_request"), maybe(REQUEST)),
    st.tuples(TEXT | st.just("error"), JSON))

# actions after which the stream is still in step (the hub has a whole frame)
WHOLE = st.one_of(
    st.tuples(st.just("event"), EVENT),
    st.tuples(st.just("text"), st.binary(max_size=40)),
    st.tuples(st.just("binary"), st.integers(0, 3), st.integers(0, 2**32 - 1),
              st.integers(0, 255), st.integers(0, 255), st.binary(max_size=70)),
    valid_message().map(binary_of),
    st.tuples(st.just("bytes"), st.binary(max_size=90)))
# actions that may leave the stream out of step: sent last, no answer awaited
BROKEN = st.one_of(
    st.tuples(st.just("frame"), st.integers(0, 15), st.booleans(),
              st.sampled_from([0, 0x10, 0x40]), st.booleans(), st.binary(max_size=130),
              st.sampled_from([None, None, 0, 126, 65535, 65536, 2**31, 2**62, 2**64 - 1])),
    st.tuples(st.just("raw"), st.binary(max_size=40)))


def act(c: RawClient, a: tuple) -> None:
    kind = a[0]
    if kind == "event":
        c.send_event(*a[1])
    elif kind == "text":
        c.send_frame(OP_TEXT, a[1].decode("utf-8", "replace").encode())
    elif kind == "binary":
        _, typ, can_id, dlc, flags, data = a
        c.send_frame(OP_BINARY, bytes([typ]) + struct.pack(">dIBB", 0.0, can_id, dlc, flags)
                     + data)
    elif kind == "bytes":
        c.send_frame(OP_BINARY, a[1])
    elif kind == "frame":
        _, op, fin, rsv, mask, payload, length = a
        c.send_frame(op, payload, fin=fin, rsv=rsv, mask=mask, length=length)
    else:
        c.send_raw(a[1])


def assert_valid(m: can.Message) -> None:
    """What reached the good client is a frame python-can itself accepts."""
    m._check()
    assert not m.is_fd or len(m.data) in CAN_FD_DLC


@settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data())
def _fuzz_example(h, a, b, data) -> None:
    first = data.draw(st.sampled_from(["valid", "valid", "fuzzed", "none"]), "bus_request")
    request = data.draw(maybe(REQUEST), "fuzzed bus_request") if first == "fuzzed" else None
    whole = data.draw(st.lists(WHOLE, max_size=5), "whole frames")
    broken = data.draw(st.lists(BROKEN, max_size=1), "then")
    c = RawClient(h.port, request=first == "valid")
    try:
        if request is not None:
            c.send_event("bus_request", request)
        for action in whole:
            act(c, action)
        if c.sync():
            for err in c.errors():
                assert isinstance(err, str) and "\n" not in err
        for action in broken:
            act(c, action)
    except (ConnectionError, Closed):
        pass                                          # the hub closed this client
    finally:
        c.close()
    for m in served(a, b):
        assert_valid(m)
    h.assert_alive()
    hub_state_bounded(h.hub)


def test_fuzzed_client_never_harms_the_hub_or_the_others():
    with running_hub() as h:
        a, b = open_remote(h.url), open_remote(h.url)
        try:
            _fuzz_example(h, a, b)
            h.assert_alive()
            assert served(a, b) is not None
            stats = h.hub.stats
            # the examples did exercise both answers: error events and dropped clients
            assert stats["bad_events"] > 50 and stats["dropped_protocol"] > 20, stats
            assert stats["dropped_session"] > 5, stats
            # ... and valid frames, which were forwarded (besides one marker per example)
            assert h.hub.frames_forwarded > EXAMPLES + 20
        finally:
            T.close_bus(a)
            T.close_bus(b)

