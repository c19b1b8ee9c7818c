"""The loopback hub against one bad client (item 6): every field of every event
and binary frame is checked; a bad field is answered with an ``error`` event, a broken
session or WebSocket stream closes that client; the hub and its other clients go on.

The hub runs in a thread of the test (`running_hub`); `RawClient` speaks the WebSocket
protocol byte by byte so that it can send what python-can-remote's client never would.
Other hub test modules import these helpers."""

from __future__ import annotations

import base64
import gc
import json
import os
import socket
import struct
import threading
import time
import traceback
import warnings
from contextlib import contextmanager

import can
import pytest

from bench.bus import selecthub as hub_mod
from bench.bus import wsproto
from bench.bus.selecthub import SelectHub
from ema_contract import transport as T

OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x1, 0x2, 0x8, 0x9, 0xA
WAIT_S = 5.0                     # bound of every wait on the hub (reached only on failure)
MARK_ID = 0x7AB                  # id of the frames the good clients exchange


class HubThread:
    """A `SelectHub` serving in a daemon thread; `error` holds what killed it, if anything."""

    def __init__(self, **kw) -> None:
        self.hub = SelectHub(**kw)
        self.port = self.hub.port
        self.url = f"ws://127.0.0.1:{self.port}/"
        self.stop = threading.Event()
        self.error: str | None = None
        self.thread = threading.Thread(target=self._run, daemon=True, name="hub-under-test")
        self.thread.start()

    def _run(self) -> None:
        try:
            self.hub.serve(self.stop)
        except BaseException:  # noqa: BLE001 - recorded for the test's assertion
            self.error = traceback.format_exc()

    def assert_alive(self) -> None:
        assert self.error is None, f"the hub died:\n{self.error}"
        assert self.thread.is_alive(), "the hub's serve loop returned"

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)


_open: list[RawClient] = []       # raw clients of the running test, closed at its end


@contextmanager
def running_hub(**kw):
    h = HubThread(**kw)
    try:
        yield h
    finally:
        while _open:
            _open.pop().close()
        h.close()


class Closed(Exception):
    """The hub closed the connection; `code` is the status of its close frame, if any."""

    def __init__(self, code: int | None, reason: str = "") -> None:
        super().__init__(f"closed by the hub: {code} {reason}")
        self.code, self.reason = code, reason


class RawClient:
    """A WebSocket client that sends exactly the bytes it is told to."""

    def __init__(self, port: int, *, upgrade: bool = True, request: bool = True,
                 config: dict | None = None, proto: str = "can.binary+json.v1",
                 rcvbuf: int | None = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        _open.append(self)
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(WAIT_S)
        self.sock.connect(("127.0.0.1", port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = bytearray()
        self.frames: list[tuple[int, bytes]] = []     # frames received, besides pongs
        self._token = 0
        if upgrade:
            self.upgrade(proto)
        if request:
            self.send_event("bus_request", {"config": config or {}})
            ev = self.next_event()
            assert ev["type"] == "bus_response", ev

    # -- sending ------------------------------------------------------------------------
    def upgrade(self, proto: str = "can.binary+json.v1") -> None:
        key = base64.b64encode(os.urandom(16)).decode()
        self.send_raw(("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
                       "Connection: Upgrade\r\nSec-WebSocket-Key: " + key + "\r\n"
                       "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: " + proto +
                       "\r\n\r\n").encode())
        head = self._read_until(b"\r\n\r\n")
        assert head.startswith(b"HTTP/1.1 101"), head

    def send_raw(self, data: bytes) -> None:
        self.sock.sendall(data)

    def send_frame(self, opcode: int, payload: bytes = b"", *, mask: bool = True,
                   fin: bool = True, length: int | None = None, rsv: int = 0) -> None:
        """One frame; `length` overrides the length header (the payload is sent as is)."""
        n = len(payload) if length is None else length
        head = bytearray([(0x80 if fin else 0) | rsv | opcode])
        mbit = 0x80 if mask else 0
        if n <= 125:
            head.append(mbit | n)
        elif n <= 0xFFFF:
            head += bytes([mbit | 126]) + struct.pack(">H", n)
        else:
            head += bytes([mbit | 127]) + struct.pack(">Q", n)
        if mask:
            key = os.urandom(4)
            head += key
            payload = bytes(b ^ key[i % 4] for i, b in enumerate(payload))
        self.send_raw(bytes(head) + payload)

    def send_event(self, kind, payload) -> None:
        self.send_text(json.dumps({"type": kind, "payload": payload}))

    def send_text(self, text: str) -> None:
        self.send_frame(OP_TEXT, text.encode())

    def send_msg(self, can_id: int, data: bytes = b"", *, dlc: int | None = None,
                 flags: int = 0, kind: int = 1) -> None:
        """A python-can-remote binary frame (type, timestamp, id, dlc, flags, data)."""
        dlc = len(data) if dlc is None else dlc
        self.send_frame(OP_BINARY, bytes([kind]) + struct.pack(">dIBB", 0.0, can_id, dlc,
                                                               flags) + data)

    # -- receiving ----------------------------------------------------------------------
    def _fill(self, deadline: float) -> None:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("no answer from the hub")
        self.sock.settimeout(left)
        try:
            chunk = self.sock.recv(65536)
        except TimeoutError:
            raise TimeoutError("no answer from the hub") from None
        except ConnectionError:
            chunk = b""
        if not chunk:
            raise Closed(None)
        self.buf += chunk

    def _read_until(self, end: bytes) -> bytes:
        deadline = time.monotonic() + WAIT_S
        while end not in self.buf:
            self._fill(deadline)
        i = self.buf.index(end) + len(end)
        head = bytes(self.buf[:i])
        del self.buf[:i]
        return head

    def _read_exactly(self, n: int, deadline: float) -> bytes:
        while len(self.buf) < n:
            self._fill(deadline)
        out = bytes(self.buf[:n])
        del self.buf[:n]
        return out

    def recv_frame(self, timeout: float = WAIT_S) -> tuple[int, bytes]:
        """The next frame (opcode, payload); raises `Closed` at a close frame or EOF."""
        deadline = time.monotonic() + timeout
        b1, b2 = self._read_exactly(2, deadline)
        n = b2 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._read_exactly(2, deadline))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._read_exactly(8, deadline))[0]
        assert not b2 & 0x80, "the hub must not mask its frames"
        payload = self._read_exactly(n, deadline)
        if b1 & 0x0F == OP_CLOSE:
            code = struct.unpack(">H", payload[:2])[0] if len(payload) >= 2 else None
            raise Closed(code, payload[2:].decode("utf-8", "replace"))
        return b1 & 0x0F, payload

    def next_event(self) -> dict:
        op, payload = self.recv_frame()
        assert op == OP_TEXT, (op, payload)
        return json.loads(payload)

    def sync(self) -> bool:
        """Ping and wait for the pong: True if the hub still serves this client (every
        frame received meanwhile lands in `frames`), False if it closed the connection."""
        self._token += 1
        tok = b"sync%d" % self._token
        try:
            self.send_frame(OP_PING, tok)
            while True:
                op, payload = self.recv_frame()
                if op == OP_PONG and payload == tok:
                    return True
                self.frames.append((op, payload))
        except (Closed, ConnectionError):
            return False

    def events(self) -> list[dict]:
        return [json.loads(p) for op, p in self.frames if op == OP_TEXT]

    def errors(self) -> list[str]:
        return [e["payload"] for e in self.events() if e.get("type") == "error"]

    def close_code(self) -> int | None:
        """Wait for the hub to close this connection; the status code it gave."""
        try:
            while True:
                self.frames.append(self.recv_frame())
        except Closed as exc:
            return exc.code

    def close(self) -> None:
        self.sock.close()


def open_remote(url: str, **kw) -> can.BusABC:
    return T.open_bus({"interface": "remote", "channel": url}, **kw)


@contextmanager
def good_pair(h: HubThread):
    """Two python-can-remote clients (the plant and the ECU of the tests)."""
    a, b = open_remote(h.url), open_remote(h.url)
    try:
        yield a, b
    finally:
        T.close_bus(a)
        T.close_bus(b)


_marks = iter(range(1 << 30))


def served(a: can.BusABC, b: can.BusABC) -> list[can.Message]:
    """`a` sends a marked frame, `b` must get it: the frames `b` got before it."""
    mark = next(_marks).to_bytes(4, "little")
    a.send(can.Message(arbitration_id=MARK_ID, data=mark, is_extended_id=False))
    before = []
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        m = b.recv(0.1)
        if m is None:
            continue
        if m.arbitration_id == MARK_ID and bytes(m.data) == mark:
            return before
        before.append(m)
    raise AssertionError(f"the good client was not served ({len(before)} other frames)")


def hub_state_bounded(hub: SelectHub) -> None:
    """Every per-client buffer and table within the hub's limits."""
    assert len(hub.clients) <= hub_mod.MAX_CLIENTS
    for c in list(hub.clients.values()):
        assert len(c.inbuf) <= hub_mod.MAX_MESSAGE_BYTES + hub_mod.RECV_BYTES
        assert len(c.outbuf) <= hub_mod.CLIENT_OUTBUF_MAX
        assert len(c.filters or ()) <= wsproto.MAX_FILTERS
        assert len(c.periodic) <= hub_mod.MAX_PERIODIC_PER_CLIENT
    assert hub.outbuf_total <= hub_mod.TOTAL_OUTBUF_MAX


GOOD_MSG = {"timestamp": 0.0, "arbitration_id": 0x321, "is_extended_id": False,
            "is_remote_frame": False, "is_error_frame": False, "dlc": 1, "data": [7]}

# one bad field of an otherwise good event: answered with `error`, the client stays
BAD_EVENTS = {
    "id 2**40": ("message", {**GOOD_MSG, "arbitration_id": 2**40, "is_extended_id": True}),
    "id -1": ("message", {**GOOD_MSG, "arbitration_id": -1}),
    "std id 0x800": ("message", {**GOOD_MSG, "arbitration_id": 0x800}),
    "dlc 300": ("message", {**GOOD_MSG, "dlc": 300}),
    "dlc 9": ("message", {**GOOD_MSG, "dlc": 9, "data": list(range(9))}),
    "dlc != len(data)": ("message", {**GOOD_MSG, "dlc": 3}),
    "data 10**8": ("message", {k: v for k, v in GOOD_MSG.items() if k != "dlc"}
                   | {"data": 10**8}),
    "data 10**8 dlc 8": ("message", {**GOOD_MSG, "dlc": 8, "data": 10**8}),
    "data byte 256": ("message", {**GOOD_MSG, "data": [256]}),
    "data byte true": ("message", {**GOOD_MSG, "data": [True]}),
    "fd length 9": ("message", {**GOOD_MSG, "is_fd": True, "dlc": 9, "data": [0] * 9}),
    "brs without fd": ("message", {**GOOD_MSG, "bitrate_switch": True}),
    "remote frame with data": ("message", {**GOOD_MSG, "is_remote_frame": True}),
    "extended flag 'yes'": ("message", {**GOOD_MSG, "is_extended_id": "yes"}),
    "timestamp string": ("message", {**GOOD_MSG, "timestamp": "now"}),
    "message payload list": ("message", [1, 2]),
    "periodic msg 5": ("periodic_start", {"msg": 5, "period": 0.01, "duration": None}),
    'period "abc"': ("periodic_start", {"msg": GOOD_MSG, "period": "abc", "duration": None}),
    "period 0": ("periodic_start", {"msg": GOOD_MSG, "period": 0, "duration": None}),
    "period 1e-4": ("periodic_start", {"msg": GOOD_MSG, "period": 1e-4, "duration": None}),
    "period NaN": ("periodic_start", {"msg": GOOD_MSG, "period": float("nan"),
                                      "duration": None}),
    "duration -1": ("periodic_start", {"msg": GOOD_MSG, "period": 0.01, "duration": -1}),
    "periodic bad msg id": ("periodic_start", {"msg": {**GOOD_MSG, "arbitration_id": -1},
                                               "period": 0.01, "duration": None}),
    "periodic_stop 'x'": ("periodic_stop", "x"),
    "unknown type": ("no_such_event", {}),
    "second bus_request": ("bus_request", {"config": {"can_filters": 5}}),
}


@pytest.mark.parametrize("kind,payload", list(BAD_EVENTS.values()), ids=list(BAD_EVENTS))
def test_a_bad_field_is_answered_with_an_error_and_everyone_else_is_served(kind, payload):
    with running_hub() as h, good_pair(h) as (a, b):
        assert served(a, b) == []
        bad = RawClient(h.port)
        bad.send_event(kind, payload)
        assert bad.sync(), "a bad field must not cost the client its connection"
        errors = bad.errors()
        assert len(errors) == 1 and errors[0] and "\n" not in errors[0], bad.frames
        h.assert_alive()
        assert served(a, b) == [], "nothing of the bad event may reach the bus"
        time.sleep(0.05)                              # a period-0 task would flood by now
        assert b.recv(0.05) is None
        assert all(not c.periodic for c in h.hub.clients.values())
        bad.send_event("message", GOOD_MSG)           # the same client is still served
        assert bad.sync()
        assert [m.arbitration_id for m in served(a, b)] == [0x321]
        hub_state_bounded(h.hub)
        bad.close()


def test_garbage_text_is_answered_with_an_error():
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port)
        for text in ("not json", "[1, 2]", '{"payload": 1}', '{"type": 5}', "[" * 30000):
            bad.send_text(text)
        assert bad.sync()
        assert len(bad.errors()) == 5
        h.assert_alive()
        assert served(a, b) == []


BAD_BINARY = {
    "id 2**32-1 not extended": dict(can_id=0xFFFFFFFF, data=b"\x01"),
    "id 0x20000000 extended": dict(can_id=0x20000000, data=b"\x01", flags=0x1),
    "dlc 255": dict(can_id=0x123, data=b"\x01", dlc=255),
    "dlc 8, 1 byte": dict(can_id=0x123, data=b"\x01", dlc=8),
    "9 data bytes": dict(can_id=0x123, data=bytes(9)),
    "unknown flag bit": dict(can_id=0x123, data=b"", flags=0x40),
    "type byte 2": dict(can_id=0x123, data=b"", kind=2),
}


@pytest.mark.parametrize("kw", list(BAD_BINARY.values()), ids=list(BAD_BINARY))
def test_a_bad_binary_frame_is_answered_with_an_error(kw):
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port)
        bad.send_msg(**kw)
        bad.send_frame(OP_BINARY, b"\x01\x02")        # shorter than the header
        assert bad.sync()
        assert len(bad.errors()) == 2, bad.frames
        assert served(a, b) == []
        bad.send_msg(0x1ABCDEF0, bytes(range(12)), flags=0x1 | 0x8 | 0x10)   # FD, extended
        assert bad.sync()
        m = served(a, b)
        assert len(m) == 1 and m[0].is_fd and m[0].bitrate_switch and m[0].is_extended_id
        assert bytes(m[0].data) == bytes(range(12))
        h.assert_alive()


BAD_REQUESTS = {
    "config [1]": {"config": [1]},
    "can_filters 5": {"config": {"can_filters": 5}},
    "filter without mask": {"config": {"can_filters": [{"can_id": 1}]}},
    "filter id -1": {"config": {"can_filters": [{"can_id": -1, "can_mask": 0x7FF}]}},
    "filter mask 2**40": {"config": {"can_filters": [{"can_id": 1, "can_mask": 2**40}]}},
    "filter extended 1": {"config": {"can_filters": [{"can_id": 1, "can_mask": 1,
                                                       "extended": 1}]}},
    "filter a string": {"config": {"can_filters": ["0x100"]}},
    "257 filters": {"config": {"can_filters": [{"can_id": i, "can_mask": 0x7FF}
                                                for i in range(257)]}},
    "receive_own_messages 'yes'": {"config": {"receive_own_messages": "yes"}},
    "payload 5": 5,
}


@pytest.mark.parametrize("payload", list(BAD_REQUESTS.values()), ids=list(BAD_REQUESTS))
def test_a_bad_bus_request_is_refused_with_an_error_and_closed(payload):
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port, request=False)
        bad.send_event("bus_request", payload)
        assert bad.close_code() == 1008
        events = bad.events()
        assert [e["type"] for e in events] == ["error"], events
        h.assert_alive()
        assert served(a, b) == []
        assert len(h.hub.clients) == 2


def test_twenty_thousand_filters_close_the_client_before_parsing():
    filters = [{"can_id": i, "can_mask": 0x1FFFFFFF, "extended": True} for i in range(20000)]
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port, request=False)
        try:
            bad.send_event("bus_request", {"config": {"can_filters": filters}})
        except ConnectionError:
            pass                                 # closed while we were still sending
        assert bad.close_code() in (1009, None)
        assert not any(e["type"] == "bus_response" for e in bad.events())
        h.assert_alive()
        assert served(a, b) == []


def test_python_can_remote_client_with_a_bad_config_gets_a_clear_error():
    with running_hub() as h, warnings.catch_warnings():
        # python-can-remote leaves the socket of a bus it could not open to the GC
        warnings.simplefilter("ignore", ResourceWarning)
        with pytest.raises(T.BusUnavailable) as exc:
            open_remote(h.url, can_filters=[{"can_id": 0x100, "can_mask": 2**40}])
        msg = str(exc.value)
        del exc
        gc.collect()
        assert "RemoteError: bus_request: can_filters[0]: can_id and can_mask must be " \
               "integers 0..0xFFFFFFFF" in msg
        assert "\n" not in msg
        h.assert_alive()


def test_length_header_of_2_62_closes_the_client_before_buffering():
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port)
        bad.send_frame(OP_BINARY, b"", length=2**62)  # the header alone, no payload
        assert bad.close_code() == 1009
        h.assert_alive()
        assert served(a, b) == []
        hub_state_bounded(h.hub)


BAD_STREAMS = {
    "unmasked": (dict(opcode=OP_TEXT, payload=b"{}", mask=False), 1002),
    "fragmented": (dict(opcode=OP_TEXT, payload=b"{", fin=False), 1002),
    "continuation": (dict(opcode=0x0, payload=b"{}"), 1002),
    "reserved bits": (dict(opcode=OP_TEXT, payload=b"{}", rsv=0x40), 1002),
    "unknown opcode": (dict(opcode=0x3, payload=b""), 1002),
    "ping of 126 bytes": (dict(opcode=OP_PING, payload=bytes(126)), 1002),
    "text not utf-8": (dict(opcode=OP_TEXT, payload=b"\xff\xfe"), 1007),
    "text of 1 MiB": (dict(opcode=OP_TEXT, payload=b" " * 100, length=1 << 20), 1009),
}


@pytest.mark.parametrize("kw,code", list(BAD_STREAMS.values()), ids=list(BAD_STREAMS))
def test_a_broken_websocket_stream_closes_that_client_only(kw, code):
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port)
        try:
            bad.send_frame(**kw)
        except ConnectionError:
            pass
        assert bad.close_code() == code
        h.assert_alive()
        assert served(a, b) == []
        assert len(h.hub.clients) == 2


def test_events_before_the_bus_request_close_the_client():
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port, request=False)
        bad.send_event("message", GOOD_MSG)
        assert bad.close_code() == 1008
        bad = RawClient(h.port, request=False)
        bad.send_msg(0x321, b"\x07")
        assert bad.close_code() == 1008
        bad = RawClient(h.port, request=False)
        bad.send_text("not json")
        assert bad.close_code() == 1008
        h.assert_alive()
        assert served(a, b) == []                     # neither frame was forwarded


def test_an_endless_handshake_is_closed():
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port, upgrade=False, request=False)
        bad.send_raw(b"GET / HTTP/1.1\r\n" + b"X-Pad: " + b"x" * 10000)
        assert bad._read_until(b"\r\n\r\n").startswith(b"HTTP/1.1 431 ")
        with pytest.raises(Closed):
            bad.recv_frame()
        h.assert_alive()
        assert served(a, b) == []


def test_an_exception_in_one_clients_handling_drops_that_client_only(monkeypatch, caplog):
    """A bug met by one client's input (here injected) costs that client its connection
    (close 1011) and one log line, never the hub."""
    real = hub_mod.message_from_json

    def buggy(m):
        if isinstance(m, dict) and m.get("arbitration_id") == 0x666:
            raise RuntimeError("boom")
        return real(m)

    monkeypatch.setattr(hub_mod, "message_from_json", buggy)
    with running_hub() as h, good_pair(h) as (a, b):
        bad = RawClient(h.port)
        bad.send_event("message", {**GOOD_MSG, "arbitration_id": 0x666})
        assert bad.close_code() == 1011
        h.assert_alive()
        assert served(a, b) == []
        lines = [r.getMessage() for r in caplog.records if r.name == "bench.bus.hub"]
        assert len(lines) == 1 and "internal error: RuntimeError: boom" in lines[0]
        assert h.hub.stats["dropped_internal"] == 1
