"""The select hub: one thread, one `selectors` loop serving every python-can-remote
client (see `bench.bus.hub` for the protocol and the process), with every limit that keeps
one bad or slow client from harming the others (docs/bus.md, "Hub limits and bad
clients")."""

from __future__ import annotations

import errno
import heapq
import itertools
import json
import logging
import resource
import selectors
import socket
import struct
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from bench.bus.wsproto import (
    BINARY_MSG,
    BINARY_TYPE,
    CHANNEL,
    CLOSE_INTERNAL,
    CLOSE_POLICY,
    F_BRS,
    F_ERR,
    F_ESI,
    F_EXT,
    F_FD,
    F_RTR,
    HANDSHAKE_MAX_BYTES,
    MAX_MESSAGE_BYTES,
    OP_BINARY,
    OP_CLOSE,
    OP_PING,
    OP_PONG,
    OP_TEXT,
    BadEvent,
    FilterSet,
    Frame,
    Violation,
    _close_frame,
    _decode_event,
    _finite,
    _parse_frame,
    _short,
    _ws_frame,
    message_from_binary,
    message_from_json,
    parse_bus_request,
    upgrade_response,
)
from ema_contract.transport import LOOPBACK_HOST, pid_alive

# -- limits (read when used; the queue caps and the client maximum when a SelectHub is made)
RECV_BYTES = 16 << 10           # read per client per loop turn
SNDBUF_BYTES = 256 << 10       # kernel send buffer per client (SO_SNDBUF; Linux doubles it)
CLIENT_OUTBUF_MAX = 4 << 20     # bytes queued in the hub for one client, beyond SNDBUF_BYTES
TOTAL_OUTBUF_MAX = 64 << 20     # bytes queued in the hub for all clients together
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
        request = bytes(c.inbuf[:end])
        del c.inbuf[:end + 4]
        answer = upgrade_response(request)
        if answer is None:
            self._http_error(c, "400 Bad Request", "not a WebSocket upgrade request")
            return False
        c.binary, response = answer
        self._write(c, response)
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
