"""The loopback CAN bus for machines without SocketCAN: a python-can-remote hub.

Clients are python-can-remote's own `RemoteBus`:
``can.Bus(interface="remote", channel="ws://127.0.0.1:PORT/")``. Every client sees every
other client's frames (and its own with ``receive_own_messages=True``), as on one CAN bus.

Two servers speak that protocol (WebSocket, ``can.binary+json.v1`` / ``can.json.v1``):

- ``--server select`` (default): a single-threaded ``selectors`` loop in this module. It
  forwards each frame to the other clients without threads, queues or copies; on a
  2-core machine it costs about a tenth of the CPU per frame of the reference server,
  which is what makes a lockstep run faster than real time (docs/performance.md).
- ``--server can_remote``: python-can-remote's ``RemoteServer`` over python-can's
  ``virtual`` interface (two threads per client), the reference implementation
  (``python -m can_remote --interface virtual -H 127.0.0.1`` is equivalent).

Both bind 127.0.0.1 only (python-can-remote's own default is 0.0.0.0), on a free port
by default, and the hub records ``{"pid", "port", "url"}`` in the state directory
(``hub.json``) so `bench status/down`, the plant and the ECU find it.

One client cannot stop the select hub or take the bus from the others (issue 9):

- Every field of every event and binary frame is checked (`check_frame`,
  `message_from_json`, `parse_bus_request`). One bad field in a well-formed event is
  answered with an ``error`` event (one line) and nothing is forwarded; the client stays,
  as a CAN driver refuses one bad frame and keeps its socket. A broken WebSocket stream
  (RFC 6455: an unmasked frame, reserved bits, an unknown opcode, a fragment, a control
  frame over 125 bytes, text that is not UTF-8, a length header over the limit) or a
  broken session (an event before the ``bus_request``, a bad ``bus_request``, none
  within 10 s) closes that client with a close code, after the ``error`` event where
  one applies: past such a fault its stream cannot be trusted.
- Memory and CPU are bounded by the limits below. A reader that does not keep up is
  dropped (reset), never left with a stream that silently misses frames.
- An exception in one client's handling (a bug, not the client's input) drops that
  client with one log line; the serve loop itself never stops on an exception.
"""

from __future__ import annotations

import argparse
import base64
import errno
import gc
import hashlib
import heapq
import itertools
import json
import logging
import math
import os
import resource
import selectors
import signal
import socket
import struct
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from can.util import CAN_FD_DLC

from ema_contract.transport import HUB_FILE, LOOPBACK_HOST, pid_alive, remove_state, write_state

CHANNEL = "ema-bench"
WS_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
# python-can-remote's binary frame: type byte 1, then timestamp, id, dlc, flags, data
BINARY_MSG = struct.Struct(">dIBB")
BINARY_TYPE = 1
BINARY_HEAD = 1 + BINARY_MSG.size           # bytes before the data
F_EXT, F_RTR, F_ERR, F_FD, F_BRS, F_ESI = 0x1, 0x2, 0x4, 0x8, 0x10, 0x20
F_ALL = F_EXT | F_RTR | F_ERR | F_FD | F_BRS | F_ESI
OP_CONT, OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
OPCODES = frozenset((OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG))
# WebSocket close codes (RFC 6455 7.4.1)
CLOSE_PROTOCOL, CLOSE_DATA, CLOSE_POLICY, CLOSE_TOO_BIG, CLOSE_INTERNAL = (
    1002, 1007, 1008, 1009, 1011)
FD_LENGTHS = frozenset(CAN_FD_DLC)           # 0-8, 12, 16, 20, 24, 32, 48, 64 bytes
STD_ID_MAX, EXT_ID_MAX = 0x7FF, 0x1FFFFFFF

# -- limits (read when used; the queue caps and the client maximum when a SelectHub is made)
HANDSHAKE_MAX_BYTES = 8 << 10   # HTTP upgrade request; python-can-remote sends ~250 bytes
MAX_MESSAGE_BYTES = 32 << 10    # one WebSocket frame's payload: a CAN FD frame is 79 bytes
#                                 binary, ~0.5 KiB as JSON; a bus_request with 256 filters
#                                 ~17 KiB. A longer length header closes the client at once.
RECV_BYTES = 16 << 10           # read per client per loop turn
SNDBUF_BYTES = 256 << 10       # kernel send buffer per client (SO_SNDBUF; Linux doubles it)
CLIENT_OUTBUF_MAX = 4 << 20     # bytes queued in the hub for one client, beyond SNDBUF_BYTES
TOTAL_OUTBUF_MAX = 64 << 20     # bytes queued in the hub for all clients together
MAX_FILTERS = 256               # acceptance filters per client
FILTER_MEMO_MAX = 4096          # remembered (id, extended) -> accepted per client
MAX_CLIENTS = 1024              # connections; further ones get HTTP 503
ACCEPTS_PER_TURN = 64           # connections accepted per loop turn
SESSION_TIMEOUT_S = 10.0        # from connect to bus_request
MIN_PERIOD_S = 1e-3             # periodic_start: one frame per SYNC period at most
MAX_PERIODIC_PER_CLIENT = 32
PERIODIC_RATE_MAX_HZ = 10_000.0  # periodic frames per second, all clients together
LOG_LINES_MAX = 100             # dropped-client lines logged in full; then every 1000th
# The reference server runs two threads per client; with CPython's default 5 ms GIL
# switch interval a thread woken by a frame can wait milliseconds for the GIL.
SWITCH_INTERVAL_S = 5e-5

log = logging.getLogger("bench.bus.hub")

Frame = tuple[int, int, int, bytes]          # can_id, dlc, flags, data


class BadEvent(ValueError):
    """One bad field in a well-formed event or binary frame: answered with an ``error``
    event; nothing is forwarded and the client stays connected."""


class Violation(Exception):
    """A broken WebSocket stream or session: the client is closed with `code`."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code


# -- validation ------------------------------------------------------------------------
def _short(value) -> str:
    """A value for an error message: one line, at most ~40 characters."""
    r = repr(value)
    return r if len(r) <= 40 else r[:37] + "..."


def _finite(value) -> float | None:
    """`value` as a float if it is a finite JSON number (not a bool), else None."""
    if type(value) not in (int, float):
        return None
    try:
        f = float(value)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def check_frame(can_id: int, dlc: int, flags: int, data: bytes) -> None:
    """Raise `BadEvent` unless this is a frame python-can and SocketCAN could carry:
    id within 11 or 29 bits by the extended flag; classic: dlc 0..8, data bytes = dlc
    (none for a remote frame); CAN FD: length one of 0-8, 12, 16, 20, 24, 32, 48, 64,
    = dlc, no remote or error frame; bitrate switch and ESI only on CAN FD."""
    if flags & ~F_ALL:
        raise BadEvent(f"unknown flag bits {flags & ~F_ALL:#x}")
    top = EXT_ID_MAX if flags & F_EXT else STD_ID_MAX
    if not 0 <= can_id <= top:
        kind = "extended" if flags & F_EXT else "standard"
        raise BadEvent(f"arbitration_id {_short(can_id)} outside 0..{top:#x} ({kind} id)")
    if flags & F_FD:
        if flags & (F_RTR | F_ERR):
            raise BadEvent("a CAN FD frame cannot be a remote or an error frame")
        if dlc not in FD_LENGTHS:
            raise BadEvent(f"CAN FD length {_short(dlc)} is not one of "
                           f"{', '.join(map(str, sorted(FD_LENGTHS)))}")
    else:
        if flags & (F_BRS | F_ESI):
            raise BadEvent("bitrate_switch and error_state_indicator need is_fd")
        if not 0 <= dlc <= 8:
            raise BadEvent(f"dlc {_short(dlc)} outside 0..8")
        if flags & F_RTR and flags & F_ERR:
            raise BadEvent("a frame cannot be a remote and an error frame")
    want = 0 if flags & F_RTR else dlc
    if len(data) != want:
        raise BadEvent(f"{len(data)} data bytes for dlc {dlc}"
                       + (" of a remote frame" if flags & F_RTR else ""))


MESSAGE_FLAGS = (("is_extended_id", F_EXT, True), ("is_remote_frame", F_RTR, False),
                 ("is_error_frame", F_ERR, False), ("is_fd", F_FD, False),
                 ("bitrate_switch", F_BRS, False), ("error_state_indicator", F_ESI, False))


def message_from_json(m) -> Frame:
    """A python-can-remote ``message`` payload (python-can's `Message` fields, its
    defaults when absent) as (can_id, dlc, flags, data); `BadEvent` if any field is bad.
    The timestamp is checked but not used: the hub stamps frames as it forwards them."""
    if not isinstance(m, dict):
        raise BadEvent(f"a message must be an object, not {_short(m)}")
    can_id = m.get("arbitration_id")
    if type(can_id) is not int:
        raise BadEvent(f"arbitration_id must be an integer, not {_short(can_id)}")
    if "timestamp" in m and _finite(m["timestamp"]) is None:
        raise BadEvent(f"timestamp must be a finite number, not {_short(m['timestamp'])}")
    flags = 0
    for key, bit, default in MESSAGE_FLAGS:
        v = m.get(key, default)
        if type(v) is not bool:
            raise BadEvent(f"{key} must be true or false, not {_short(v)}")
        flags |= bit if v else 0
    raw = m.get("data", [])
    if not isinstance(raw, list) or len(raw) > 64 or not all(
            type(b) is int and 0 <= b <= 255 for b in raw):
        raise BadEvent(f"data must be a list of at most 64 integers 0..255, not {_short(raw)}")
    dlc = m.get("dlc", len(raw))
    if type(dlc) is not int:
        raise BadEvent(f"dlc must be an integer, not {_short(dlc)}")
    data = bytes(raw)
    check_frame(can_id, dlc, flags, data)
    return can_id, dlc, flags, data


def message_from_binary(payload: bytes) -> Frame:
    """A python-can-remote binary frame as (can_id, dlc, flags, data); `BadEvent` if bad.
    Its timestamp is not used (the hub stamps frames as it forwards them)."""
    if len(payload) < BINARY_HEAD:
        raise BadEvent(f"binary frame of {len(payload)} bytes, shorter than its "
                       f"{BINARY_HEAD}-byte header")
    if payload[0] != BINARY_TYPE:
        raise BadEvent(f"binary frame of unknown type {payload[0]}")
    _, can_id, dlc, flags = BINARY_MSG.unpack_from(payload, 1)
    data = payload[BINARY_HEAD:]
    if flags or can_id > STD_ID_MAX or dlc > 8 or len(data) != dlc:   # else: valid, classic
        check_frame(can_id, dlc, flags, data)
    return can_id, dlc, flags, data


class FilterSet:
    """python-can's acceptance filters (`can.BusABC.set_filters`: a frame passes if
    ``id & can_mask == can_id & can_mask`` for one filter, and ``extended``, when given,
    equals its extended flag), matched in O(1) per frame: filters are grouped by mask
    into id sets, and each (id, extended) seen is remembered (at most `FILTER_MEMO_MAX`),
    so a client's filters cost a dictionary look-up per frame however many it has."""

    def __init__(self, filters: list[tuple[int, int, bool | None]]) -> None:
        self.filters = filters
        groups: dict[bool, dict[int, set[int]]] = {False: {}, True: {}}
        for can_id, mask, ext in filters:
            for side in ((False, True) if ext is None else (ext,)):
                groups[side].setdefault(mask, set()).add(can_id & mask)
        self._groups = {side: list(g.items()) for side, g in groups.items()}
        self._memo: dict[int, bool] = {}
        self.evaluations = 0                     # (id, extended) pairs matched in full

    @classmethod
    def parse(cls, raw) -> FilterSet | None:
        """`can_filters` of a bus_request; None (no filter: every frame) for null or []."""
        if raw is None or raw == []:
            return None
        if not isinstance(raw, list):
            raise BadEvent(f"can_filters must be a list of filters, not {_short(raw)}")
        if len(raw) > MAX_FILTERS:
            raise BadEvent(f"can_filters: {len(raw)} filters, at most {MAX_FILTERS}")
        out: list[tuple[int, int, bool | None]] = []
        for i, f in enumerate(raw):
            if not isinstance(f, dict):
                raise BadEvent(f"can_filters[{i}] must be an object, not {_short(f)}")
            vals: list[Any] = [f.get("can_id"), f.get("can_mask")]   # JSON values
            if not all(type(v) is int and 0 <= v <= 0xFFFFFFFF for v in vals):
                raise BadEvent(f"can_filters[{i}]: can_id and can_mask must be integers "
                               f"0..0xFFFFFFFF, not {_short(vals)}")
            ext = f.get("extended")
            if "extended" in f and type(ext) is not bool:
                raise BadEvent(f"can_filters[{i}]: extended must be true or false, "
                               f"not {_short(ext)}")
            out.append((vals[0], vals[1], ext))
        return cls(out)

    def __len__(self) -> int:
        return len(self.filters)

    def accepts(self, can_id: int, ext: bool) -> bool:
        key = can_id << 1 | ext
        hit = self._memo.get(key)
        if hit is None:
            self.evaluations += 1
            hit = any(can_id & mask in ids for mask, ids in self._groups[ext])
            if len(self._memo) >= FILTER_MEMO_MAX:
                self._memo.clear()
            self._memo[key] = hit
        return hit


def parse_bus_request(payload) -> tuple[bool, FilterSet | None]:
    """(receive_own_messages, filters) of a bus_request payload ``{"config": {...}}``;
    other configuration keys (bitrate, fd, ...) mean nothing on a loopback bus."""
    if not isinstance(payload, dict):
        raise BadEvent(f"payload must be an object, not {_short(payload)}")
    cfg = payload.get("config", {})
    if not isinstance(cfg, dict):
        raise BadEvent(f"config must be an object, not {_short(cfg)}")
    own = cfg.get("receive_own_messages", False)
    if own is not None and type(own) is not bool:
        raise BadEvent(f"receive_own_messages must be true or false, not {_short(own)}")
    return bool(own), FilterSet.parse(cfg.get("can_filters"))


# -- WebSocket framing -------------------------------------------------------------------
def _ws_frame(opcode: int, payload: bytes) -> bytes:
    n = len(payload)
    if n <= 125:
        head = bytes((0x80 | opcode, n))
    elif n <= 0xFFFF:
        head = bytes((0x80 | opcode, 126)) + struct.pack(">H", n)
    else:
        head = bytes((0x80 | opcode, 127)) + struct.pack(">Q", n)
    return head + payload


def _close_frame(code: int, reason: str) -> bytes:
    return _ws_frame(OP_CLOSE, struct.pack(">H", code) + reason.encode("ascii", "replace")[:123])


def _parse_frame(buf: bytearray, limit: int = MAX_MESSAGE_BYTES
                 ) -> tuple[int, bytes, int] | None:
    """(opcode, unmasked payload, bytes used) of the first complete client frame, None
    if it is not complete yet; `Violation` for what RFC 6455 makes a client fail (no
    mask, reserved bits, unknown opcode, control frame over 125 bytes or fragmented)
    and for fragmented messages and payloads over `limit` bytes, which python-can-remote
    never sends. The length header alone decides: nothing more is buffered."""
    if len(buf) < 2:
        return None
    b1 = buf[0]
    op = _client_opcode(b1, buf[1])
    length = _payload_length(buf)
    if length is None:
        return None
    n, pos = length
    if op >= 8 and (n > 125 or not b1 & 0x80):
        raise Violation(CLOSE_PROTOCOL, "control frames must be whole and <= 125 bytes")
    if n > limit:
        raise Violation(CLOSE_TOO_BIG, f"frame of {n} bytes over the {limit}-byte limit")
    if len(buf) < pos + 4 + n:
        return None
    mask = bytes(buf[pos:pos + 4])
    pos += 4
    return op, _unmask(mask, bytes(buf[pos:pos + n])), pos + n


def _client_opcode(b1: int, b2: int) -> int:
    """The opcode of a client frame whose first two bytes are `b1`, `b2`; `Violation`
    for reserved bits, fragments, an unknown opcode or a missing mask."""
    op = b1 & 0x0F
    if b1 & 0x70:
        raise Violation(CLOSE_PROTOCOL, "reserved bits set (no extension negotiated)")
    if op == OP_CONT or (not b1 & 0x80 and op < 8):
        raise Violation(CLOSE_PROTOCOL, "fragmented messages are not supported")
    if op not in OPCODES:
        raise Violation(CLOSE_PROTOCOL, f"unknown opcode {op:#x}")
    if not b2 & 0x80:
        raise Violation(CLOSE_PROTOCOL, "client frames must be masked (RFC 6455 5.1)")
    return op


def _payload_length(buf: bytearray) -> tuple[int, int] | None:
    """(payload length, where the mask starts) from a frame's length header (7, 16 or
    64 bits), None if the header is not complete yet."""
    n = buf[1] & 0x7F
    if n == 126:
        if len(buf) < 4:
            return None
        return struct.unpack_from(">H", buf, 2)[0], 4
    if n == 127:
        if len(buf) < 10:
            return None
        return struct.unpack_from(">Q", buf, 2)[0], 10
    return n, 2


def _unmask(mask: bytes, data: bytes) -> bytes:
    """`data` XORed with the repeated 4-byte `mask` (RFC 6455 5.3)."""
    n = len(data)
    if not n:
        return data
    m = (mask * (n // 4 + 1))[:n]
    return (int.from_bytes(data, "big") ^ int.from_bytes(m, "big")).to_bytes(n, "big")


def _decode_event(payload: bytes) -> tuple[Any, str | None]:
    """(the JSON event, None) or (None-or-value, why it is malformed) of a text frame's
    payload; `Violation` if it is not UTF-8."""
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError:
        raise Violation(CLOSE_DATA, "text frame is not valid UTF-8") from None
    try:
        ev = json.loads(text)
    except (ValueError, RecursionError) as exc:
        return None, f"malformed event: not JSON ({type(exc).__name__})"
    if isinstance(ev, dict) and type(ev.get("type")) is str:
        return ev, None
    return ev, "malformed event: not an object with a string 'type'"


# -- the hub -----------------------------------------------------------------------------
@dataclass(eq=False)
class Periodic:
    """A python-can-remote periodic task, sent by the hub on its client's behalf."""
    client: Client
    frame: Frame
    period: float
    end: float | None
    live: bool = True


@dataclass(eq=False)
class Client:
    """One WebSocket connection."""
    sock: socket.socket
    addr: str
    fd: int = -1
    since: float = 0.0           # time.monotonic() at accept
    inbuf: bytearray = field(default_factory=bytearray)
    outbuf: bytearray = field(default_factory=bytearray)
    upgraded: bool = False
    ready: bool = False          # bus_request answered
    binary: bool = True          # can.binary+json.v1 (else can.json.v1)
    own: bool = False            # receive_own_messages
    filters: FilterSet | None = None
    bad_events: int = 0
    closing: bool = False
    abort: bool = False          # close with RST: drop what the kernel still holds for it
    events: int = selectors.EVENT_READ
    periodic: dict[int, Periodic] = field(default_factory=dict)   # by arbitration id


class SelectHub:
    """Single-threaded python-can-remote-compatible hub (see module docstring).

    One client can never stop it: every event and frame is checked; what a client does
    wrong costs that client an ``error`` event or its connection, never the hub (any
    exception in a client's handling drops that client, with one log line)."""

    def __init__(self, host: str = LOOPBACK_HOST, port: int = 0) -> None:
        soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        self.max_clients = MAX_CLIENTS if soft == resource.RLIM_INFINITY else max(
            1, min(MAX_CLIENTS, soft - 64))
        self.handshake_max = HANDSHAKE_MAX_BYTES
        self.message_max = MAX_MESSAGE_BYTES
        self.client_outbuf_max = CLIENT_OUTBUF_MAX
        self.total_outbuf_max = TOTAL_OUTBUF_MAX
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, port))
        self.listener.listen(max(socket.SOMAXCONN, 1024))   # the kernel caps it (somaxconn)
        self.listener.setblocking(False)
        self.port = self.listener.getsockname()[1]
        self.sel = selectors.DefaultSelector()
        self.sel.register(self.listener, selectors.EVENT_READ, None)
        self._accept_paused_until = 0.0
        self.clients: dict[int, Client] = {}
        self._dirty: set[Client] = set()
        self._pending: set[Client] = set()       # connected, no bus_request yet
        self._heap: list[tuple[float, int, Periodic]] = []
        self._seq = itertools.count()
        self._heap_dead = 0
        self.periodic_rate = 0.0                 # Hz, all live periodic tasks
        self.outbuf_total = 0
        self.outbuf_peak = 0
        self.frames_forwarded = 0
        self.stats: Counter[str] = Counter()
        self._notes = 0

    # -- plumbing -----------------------------------------------------------------------
    def _note(self, msg: str) -> None:
        """One log line (the first `LOG_LINES_MAX`, then every 1000th)."""
        self._notes += 1
        if self._notes <= LOG_LINES_MAX or self._notes % 1000 == 0:
            log.warning("%s", msg if self._notes <= LOG_LINES_MAX
                        else f"{msg} ({self._notes} such lines, most not logged)")

    def _accept(self) -> None:
        for _ in range(ACCEPTS_PER_TURN):
            try:
                sock, addr = self.listener.accept()
            except BlockingIOError:
                return
            except OSError as exc:
                if exc.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    self._pause_accept(exc)
                return
            if len(self.clients) >= self.max_clients:
                self._refuse(sock, f"{addr[0]}:{addr[1]}")
                continue
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SNDBUF_BYTES)
            c = Client(sock, f"{addr[0]}:{addr[1]}", sock.fileno(), time.monotonic())
            self.clients[c.fd] = c
            self._pending.add(c)
            self.sel.register(sock, selectors.EVENT_READ, c)

    def _refuse(self, sock: socket.socket, addr: str) -> None:
        self.stats["refused_full"] += 1
        self._note(f"refused {addr}: {self.max_clients} clients already")
        try:
            sock.setblocking(False)
            sock.send(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n"
                      b"Connection: close\r\n\r\n")
        except OSError:
            pass
        sock.close()

    def _pause_accept(self, exc: OSError) -> None:
        """Out of file descriptors: stop accepting for 0.1 s instead of spinning."""
        self._note(f"cannot accept connections: {exc}")
        if not self._accept_paused_until:
            self.sel.unregister(self.listener)
        self._accept_paused_until = time.monotonic() + 0.1

    def _close(self, c: Client, reason: str | None, kind: str) -> None:
        """Mark `c` for dropping at the end of this loop turn and free what it holds;
        `reason` is logged (one line) unless None (an ordinary disconnect)."""
        if c.closing:
            return
        c.closing = True
        self.stats[kind] += 1
        if reason is not None:
            self._note(f"dropped client {c.addr}: {reason}")
        self.outbuf_total -= len(c.outbuf)
        c.outbuf = bytearray()
        c.inbuf = bytearray()
        for task in list(c.periodic.values()):
            self._stop_task(task)

    def _fail(self, c: Client, code: int, reason: str, error: str | None = None,
              kind: str = "dropped_protocol") -> None:
        """Close `c` for a protocol or session violation: the ``error`` event (if any) and
        a close frame with `code` are sent first, as far as the socket takes them."""
        if c.closing:
            return
        if error is not None:
            self._send_json(c, "error", error)
        if c.upgraded:
            self._write(c, _close_frame(code, reason))
        if not c.closing:
            self._flush(c)
        self._close(c, f"{reason} (close {code})", kind)

    def _drop(self, c: Client) -> None:
        if not c.closing:
            self._close(c, None, "disconnected")
        self._pending.discard(c)
        if self.clients.get(c.fd) is c:
            del self.clients[c.fd]
            try:
                self.sel.unregister(c.sock)
            except (KeyError, ValueError, OSError):
                pass
        try:
            if c.abort:
                c.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            c.sock.close()
        except OSError:
            pass

    def _write(self, c: Client, data: bytes) -> None:
        """Queue `data` for `c`; queues are flushed once per loop turn (one send per
        client for all the frames of that turn: fewer syscalls and wake-ups). A client
        whose queue passes its cap, or the largest queues when all of them pass the
        hub's budget, are dropped: a reader that does not keep up loses its connection,
        never single frames."""
        if c.closing:
            return
        out = c.outbuf
        out += data
        self.outbuf_total += len(data)
        self._dirty.add(c)
        if len(out) > self.client_outbuf_max or self.outbuf_total > self.total_outbuf_max:
            self._over_budget(c)

    def _over_budget(self, c: Client | None) -> None:
        """Drop `c` if over its cap, then the largest queues while over the budget."""
        if c is not None and len(c.outbuf) > self.client_outbuf_max:
            self._drop_slow(c, f"over {self.client_outbuf_max} bytes queued (not reading)")
        while self.outbuf_total > self.total_outbuf_max:
            big = max(self.clients.values(), key=lambda k: len(k.outbuf), default=None)
            if big is None or not big.outbuf:    # cannot happen; never loop on it
                self.outbuf_total = sum(len(k.outbuf) for k in self.clients.values())
                return
            self._drop_slow(big, f"largest queue ({len(big.outbuf)} bytes) when all clients "
                                 f"had over {self.total_outbuf_max} bytes queued")

    def _drop_slow(self, c: Client, reason: str) -> None:
        """A reader that does not keep up: closed at once, with a reset (what is queued
        for it, here and in the kernel, is freed; it would read a cut stream anyway)."""
        c.abort = True
        self._close(c, reason, "dropped_slow")

    def _flush(self, c: Client) -> None:
        if not c.outbuf or c.closing:
            return
        try:
            sent = c.sock.send(c.outbuf)
        except BlockingIOError:
            sent = 0
        except OSError as exc:
            self._close(c, None if isinstance(exc, ConnectionError) else str(exc),
                        "disconnected")
            return
        del c.outbuf[:sent]
        self.outbuf_total -= sent
        want = selectors.EVENT_READ | (selectors.EVENT_WRITE if c.outbuf else 0)
        if want != c.events:
            self.sel.modify(c.sock, want, c)
            c.events = want

    def _guard(self, c: Client | None, fn, *args) -> None:
        """Run one client's handling; an exception (a bug, never the client's input)
        drops that client with one log line instead of ending the hub."""
        try:
            fn(*args)
        except Exception as exc:  # noqa: BLE001 - the hub must outlive any one client
            what = f"{type(exc).__name__}: {exc}"[:200]
            if c is None:
                self._note(f"internal error: {what}")
                return
            try:
                self._fail(c, CLOSE_INTERNAL, f"internal error: {what}", kind="dropped_internal")
            except Exception:  # noqa: BLE001
                c.closing = True
                self._note(f"dropped client {c.addr} after an internal error: {what}")

    # -- protocol -----------------------------------------------------------------------
    def _handshake(self, c: Client) -> bool:
        end = c.inbuf.find(b"\r\n\r\n")
        if end < 0 or end > self.handshake_max:
            if len(c.inbuf) > self.handshake_max:
                self._http_error(c, "431 Request Header Fields Too Large",
                                 f"handshake over {self.handshake_max} bytes")
            return False
        head = bytes(c.inbuf[:end]).decode("latin-1").split("\r\n")
        del c.inbuf[:end + 4]
        headers = {}
        for line in head[1:]:
            k, _, v = line.partition(":")
            headers[k.strip().lower()] = v.strip()
        key = headers.get("sec-websocket-key")
        if not head[0].startswith("GET ") or headers.get("upgrade", "").lower() != "websocket" \
                or not key:
            self._http_error(c, "400 Bad Request", "not a WebSocket upgrade request")
            return False
        protos = [p.strip() for p in headers.get("sec-websocket-protocol", "").split(",")]
        proto = "can.binary+json.v1" if "can.binary+json.v1" in protos else "can.json.v1"
        c.binary = proto == "can.binary+json.v1"
        accept = base64.b64encode(hashlib.sha1(key.encode() + WS_GUID).digest()).decode()
        self._write(c, ("HTTP/1.1 101 Switching Protocols\r\nUpgrade: WebSocket\r\n"
                        "Connection: Upgrade\r\nSec-WebSocket-Accept: " + accept + "\r\n"
                        "Sec-WebSocket-Protocol: " + proto + "\r\n\r\n").encode())
        c.upgraded = True
        return True

    def _http_error(self, c: Client, status: str, reason: str) -> None:
        self._write(c, f"HTTP/1.1 {status}\r\nContent-Length: 0\r\n"
                       f"Connection: close\r\n\r\n".encode())
        self._flush(c)
        self._close(c, reason, "dropped_protocol")

    def _bad(self, c: Client, reason: str) -> None:
        """Answer one bad event or frame with an ``error`` event (one line)."""
        c.bad_events += 1
        self.stats["bad_events"] += 1
        self._send_json(c, "error", reason.replace("\n", " ")[:300])

    def _event(self, c: Client, payload: bytes) -> None:
        ev, bad = _decode_event(payload)
        if bad is not None:
            if not c.ready:
                raise Violation(CLOSE_POLICY, f"{bad}, before bus_request")
            self._bad(c, bad)
            return
        kind, payload = ev["type"], ev.get("payload")
        if not c.ready:
            self._session(c, kind, payload)
            return
        try:
            self._dispatch(c, kind, payload)
        except BadEvent as exc:
            self._bad(c, f"{kind[:40]}: {exc}")

    def _dispatch(self, c: Client, kind: str, payload: Any) -> None:
        """Act on one well-formed event of a ready client; `BadEvent` if it is wrong."""
        if kind == "message":
            self._forward(c, *message_from_json(payload))
        elif kind == "periodic_start":
            self._periodic_start(c, payload)
        elif kind == "periodic_stop":
            if type(payload) is not int:
                raise BadEvent(f"payload must be an arbitration_id, not {_short(payload)}")
            task = c.periodic.get(payload)
            if task is not None:
                self._stop_task(task)
        elif kind == "error":              # python-can-remote's client reporting one
            self.stats["client_errors"] += 1
        elif kind == "bus_request":
            raise BadEvent("the bus is already set up for this connection")
        else:
            raise BadEvent("unknown event type")

    def _session(self, c: Client, kind: str, payload) -> None:
        """The first event must be a valid bus_request; anything else closes `c`."""
        if kind != "bus_request":
            raise Violation(CLOSE_POLICY, f"{kind[:40]!r} event before bus_request")
        try:
            c.own, c.filters = parse_bus_request(payload)
        except BadEvent as exc:
            self._fail(c, CLOSE_POLICY, "bad bus_request", error=f"bus_request: {exc}",
                       kind="dropped_session")
            return
        c.ready = True
        self._pending.discard(c)
        self._send_json(c, "bus_response", {"channel_info": f"Loopback hub channel {CHANNEL}"})

    def _send_json(self, c: Client, kind: str, payload) -> None:
        self._write(c, _ws_frame(OP_TEXT, json.dumps({"type": kind,
                                                      "payload": payload}).encode()))

    def _forward(self, src: Client | None, can_id: int, dlc: int, flags: int,
                 data: bytes) -> None:
        """Deliver one (checked) CAN frame to every client that should see it (queued as
        in `_write`, inline: this is the hub's hot path)."""
        ts = time.time()
        ext = bool(flags & F_EXT)
        binary = json_frame = None
        self.frames_forwarded += 1
        cap, queued, over, dirty = self.client_outbuf_max, 0, [], self._dirty
        for c in list(self.clients.values()):
            if not c.ready or c.closing or (c is src and not c.own):
                continue
            if c.filters is not None and not c.filters.accepts(can_id, ext):
                continue
            if c.binary:
                if binary is None:
                    binary = _ws_frame(OP_BINARY, bytes((BINARY_TYPE,)) + BINARY_MSG.pack(
                        ts, can_id, dlc, flags) + data)
                frame = binary
            else:
                if json_frame is None:
                    m = {"timestamp": ts, "arbitration_id": can_id, "is_extended_id": ext,
                         "is_remote_frame": bool(flags & F_RTR),
                         "is_error_frame": bool(flags & F_ERR), "dlc": dlc,
                         "data": list(data)}
                    if flags & F_FD:           # as python-can-remote's own send_msg
                        m.update(is_fd=True, bitrate_switch=bool(flags & F_BRS),
                                 error_state_indicator=bool(flags & F_ESI))
                    json_frame = _ws_frame(OP_TEXT, json.dumps(
                        {"type": "message", "payload": m}).encode())
                frame = json_frame
            out = c.outbuf
            out += frame
            queued += len(frame)
            dirty.add(c)
            if len(out) > cap:
                over.append(c)
        self.outbuf_total += queued
        if over or self.outbuf_total > self.total_outbuf_max:
            for c in over:
                self._over_budget(c)
            self._over_budget(None)

    def _frame(self, c: Client, op: int, payload: bytes) -> None:
        if op == OP_BINARY:
            if not c.ready:
                raise Violation(CLOSE_POLICY, "binary frame before bus_request")
            try:
                frame = message_from_binary(payload)
            except BadEvent as exc:
                self._bad(c, f"binary message: {exc}")
                return
            self._forward(c, *frame)
        elif op == OP_TEXT:
            self._event(c, payload)
        elif op == OP_PING:
            self._write(c, _ws_frame(OP_PONG, payload))
        elif op == OP_CLOSE:
            self._write(c, _ws_frame(OP_CLOSE, payload[:2]))
            self._flush(c)
            self._close(c, None, "disconnected")

    def _read(self, c: Client) -> None:
        try:
            chunk = c.sock.recv(RECV_BYTES)
        except BlockingIOError:
            return
        except OSError:
            self._close(c, None, "disconnected")
            return
        if not chunk:
            self._close(c, None, "disconnected")
            return
        c.inbuf += chunk
        if not c.upgraded and not self._handshake(c):
            return
        try:
            while not c.closing:
                got = _parse_frame(c.inbuf, self.message_max)
                if got is None:
                    return
                op, payload, used = got
                del c.inbuf[:used]
                if op == OP_BINARY and c.ready:  # the common case first
                    try:
                        frame = message_from_binary(payload)
                    except BadEvent as exc:
                        self._bad(c, f"binary message: {exc}")
                        continue
                    self._forward(c, *frame)
                else:
                    self._frame(c, op, payload)
        except Violation as v:
            self._fail(c, v.code, str(v))

    # -- periodic tasks -----------------------------------------------------------------
    def _periodic_start(self, c: Client, payload) -> None:
        if not isinstance(payload, dict):
            raise BadEvent(f"payload must be an object, not {_short(payload)}")
        frame = message_from_json(payload.get("msg"))
        period = _finite(payload.get("period"))
        if period is None or period < MIN_PERIOD_S:
            raise BadEvent(f"period must be a finite number >= {MIN_PERIOD_S} s, "
                           f"not {_short(payload.get('period'))}")
        dur = payload.get("duration")
        if dur is not None and (_finite(dur) is None or dur < 0):
            raise BadEvent(f"duration must be null or a finite number >= 0, not {_short(dur)}")
        old = c.periodic.get(frame[0])
        if old is None and len(c.periodic) >= MAX_PERIODIC_PER_CLIENT:
            raise BadEvent(f"at most {MAX_PERIODIC_PER_CLIENT} periodic tasks per client")
        rate = self.periodic_rate - (1.0 / old.period if old else 0.0) + 1.0 / period
        if rate > PERIODIC_RATE_MAX_HZ * (1 + 1e-9):
            raise BadEvent(f"the hub sends at most {PERIODIC_RATE_MAX_HZ:.0f} periodic "
                           f"frames per second")
        if old is not None:
            self._stop_task(old)
        now = time.monotonic()
        task = Periodic(c, frame, period, None if dur is None else now + float(dur))
        c.periodic[frame[0]] = task
        self.periodic_rate += 1.0 / period
        heapq.heappush(self._heap, (now, next(self._seq), task))   # first frame at once

    def _stop_task(self, task: Periodic, in_heap: bool = True) -> None:
        """End `task` (stopped, replaced, its client gone, or its duration over); its heap
        entry, if it has one, is skipped when it comes up."""
        if not task.live:
            return
        task.live = False
        if task.client.periodic.get(task.frame[0]) is task:
            del task.client.periodic[task.frame[0]]
        self.periodic_rate = max(self.periodic_rate - 1.0 / task.period, 0.0)
        self._heap_dead += in_heap

    def _periodic(self) -> float:
        """Send the periodic frames that are due; seconds until the next one (<= 0.5)."""
        if self._heap_dead > 64 and 2 * self._heap_dead > len(self._heap):
            self._heap = [e for e in self._heap if e[2].live]      # stopped tasks' entries
            heapq.heapify(self._heap)
            self._heap_dead = 0
            self.periodic_rate = sum(1.0 / e[2].period for e in self._heap)
        now = time.monotonic()
        heap = self._heap
        while heap and heap[0][0] <= now:
            due, _, task = heapq.heappop(heap)
            if not task.live:
                self._heap_dead -= 1
                continue
            if task.end is not None and now >= task.end:
                self._stop_task(task, in_heap=False)
                continue
            self._guard(task.client, self._forward, task.client, *task.frame)
            nxt = due + task.period
            if nxt <= now:                       # late: no burst to catch up
                nxt = now + task.period
            if task.end is not None:
                nxt = min(nxt, task.end)
            # pushed back even if stopped meanwhile: then it is a counted dead entry
            heapq.heappush(heap, (nxt, next(self._seq), task))
        return min(max(heap[0][0] - now, 0.0), 0.5) if heap else 0.5

    # -- loop ---------------------------------------------------------------------------
    def _housekeeping(self, now: float) -> None:
        """Every 0.2 s: sessions that never started, accepting again after EMFILE."""
        for c in [c for c in self._pending if now - c.since > SESSION_TIMEOUT_S]:
            self._fail(c, CLOSE_POLICY, f"no bus_request within {SESSION_TIMEOUT_S:g} s",
                       kind="dropped_session")
        if self._accept_paused_until and now >= self._accept_paused_until:
            self._accept_paused_until = 0.0
            self.sel.register(self.listener, selectors.EVENT_READ, None)

    def step(self, timeout: float) -> None:
        """One loop turn: periodic frames, socket events, flushes, drops."""
        timeout = min(self._periodic(), timeout)
        for key, mask in self.sel.select(timeout):
            c = key.data
            if c is None:
                self._guard(None, self._accept)
                continue
            if mask & selectors.EVENT_READ:
                self._guard(c, self._read, c)
            if mask & selectors.EVENT_WRITE:
                self._dirty.add(c)
        if self.outbuf_total > self.outbuf_peak:   # queues are longest just before flushing
            self.outbuf_peak = self.outbuf_total
        for _ in range(2):                       # writes made while flushing: once more
            dirty, self._dirty = self._dirty, set()
            for c in dirty:
                self._guard(c, self._flush, c)
        for c in [c for c in self.clients.values() if c.closing]:
            self._drop(c)

    def serve(self, stop: threading.Event, parent_pid: int | None = None) -> None:
        next_check = time.monotonic() + 0.2
        while not stop.is_set():
            try:
                self.step(0.2)
                now = time.monotonic()
                if now >= next_check:
                    next_check = now + 0.2
                    self._housekeeping(now)
                    if parent_pid and not pid_alive(parent_pid):
                        break
            except Exception as exc:  # noqa: BLE001 - never die; say it once, go on
                self._note(f"internal error in the serve loop: {type(exc).__name__}: {exc}")
                time.sleep(0.01)
        self.close()

    def close(self) -> None:
        for c in list(self.clients.values()):
            self._drop(c)
        self.sel.close()
        self.listener.close()


def serve(port: int = 0, state: bool = True, parent_pid: int | None = None,
          server: str = "select") -> int:
    """Serve until SIGTERM/SIGINT (or until `parent_pid` exits); returns an exit code."""
    stop = threading.Event()

    def on_signal(signum, frame):  # noqa: ARG001
        stop.set()

    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    if server == "select":
        hub = SelectHub(LOOPBACK_HOST, port)
        port = hub.port
        ref = None
    else:
        from can_remote import RemoteServer
        logging.getLogger("can_remote").setLevel(logging.WARNING)
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        ref = RemoteServer(LOOPBACK_HOST, port, bustype="virtual", channel=CHANNEL)
        port = ref.server_port
    url = f"ws://{LOOPBACK_HOST}:{port}/"
    gc.collect()
    gc.freeze()       # the imported modules are permanent: no full-GC stalls while serving
    if state:
        write_state(HUB_FILE, {"pid": os.getpid(), "port": port, "url": url,
                               "server": server})
    print(url, flush=True)
    try:
        if ref is None:
            hub.serve(stop, parent_pid)
        else:
            th = threading.Thread(target=ref.serve_forever, kwargs={"poll_interval": 0.1},
                                  daemon=True, name="hub")
            th.start()
            while not stop.wait(0.2):
                if parent_pid and not pid_alive(parent_pid):
                    break
            ref.shutdown()
            ref.server_close()
    finally:
        if state:
            remove_state(HUB_FILE, os.getpid())
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.bus.hub",
                                 description="Loopback CAN hub for python-can-remote clients, "
                                             "bound to 127.0.0.1.")
    ap.add_argument("--port", type=int, default=0, help="TCP port (default: a free one)")
    ap.add_argument("--server", choices=["select", "can_remote"], default="select",
                    help="select: single-threaded hub (default); can_remote: "
                         "python-can-remote's RemoteServer over the virtual interface")
    ap.add_argument("--no-state", action="store_true",
                    help="do not record the hub in the state directory")
    ap.add_argument("--parent-pid", type=int, default=None, metavar="PID",
                    help="exit when process PID exits")
    args = ap.parse_args(argv)
    # dropped clients, one line each, into the hub's log (its stderr; stdout is closed)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr,
                        format="%(asctime)s hub: %(message)s")
    try:
        return serve(args.port, state=not args.no_state, parent_pid=args.parent_pid,
                     server=args.server)
    except OSError as exc:
        print(f"error: cannot start the hub: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
