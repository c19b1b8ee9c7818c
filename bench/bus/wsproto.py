"""The loopback hub's wire protocol (python-can-remote over WebSocket, RFC 6455): frame
and event validation, acceptance filters, WebSocket framing. Pure functions and data; the
server that applies them is `bench.bus.hub`."""

from __future__ import annotations

import base64
import hashlib
import json
import math
import struct
from typing import Any

from can.util import CAN_FD_DLC

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


HANDSHAKE_MAX_BYTES = 8 << 10   # HTTP upgrade request; python-can-remote sends ~250 bytes
MAX_MESSAGE_BYTES = 32 << 10    # one WebSocket frame's payload: a CAN FD frame is 79 bytes
#                                 binary, ~0.5 KiB as JSON; a bus_request with 256 filters
#                                 ~17 KiB. A longer length header closes the client at once.
MAX_FILTERS = 256               # acceptance filters per client
FILTER_MEMO_MAX = 4096          # remembered (id, extended) -> accepted per client

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


def upgrade_response(request: bytes) -> tuple[bool, bytes] | None:
    """(binary protocol?, the 101 response) for an HTTP WebSocket upgrade request (the
    bytes before the blank line), or None when it is not one (RFC 6455 4.2)."""
    head = request.decode("latin-1").split("\r\n")
    headers = {}
    for line in head[1:]:
        k, _, v = line.partition(":")
        headers[k.strip().lower()] = v.strip()
    key = headers.get("sec-websocket-key")
    if not head[0].startswith("GET ") or headers.get("upgrade", "").lower() != "websocket" \
            or not key:
        return None
    protos = [p.strip() for p in headers.get("sec-websocket-protocol", "").split(",")]
    proto = "can.binary+json.v1" if "can.binary+json.v1" in protos else "can.json.v1"
    accept = base64.b64encode(hashlib.sha1(key.encode() + WS_GUID).digest()).decode()
    return proto == "can.binary+json.v1", (
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: WebSocket\r\n"
        "Connection: Upgrade\r\nSec-WebSocket-Accept: " + accept + "\r\n"
        "Sec-WebSocket-Protocol: " + proto + "\r\n\r\n").encode()
