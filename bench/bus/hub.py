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
"""

from __future__ import annotations

import argparse
import base64
import gc
import hashlib
import json
import logging
import os
import selectors
import signal
import socket
import struct
import sys
import threading
import time
from dataclasses import dataclass, field

from ema_contract.transport import HUB_FILE, LOOPBACK_HOST, pid_alive, remove_state, write_state

CHANNEL = "ema-bench"
WS_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
# python-can-remote's binary frame: type byte 1, then timestamp, id, dlc, flags, data
BINARY_MSG = struct.Struct(">dIBB")
BINARY_TYPE = 1
F_EXT, F_RTR, F_ERR, F_FD, F_BRS, F_ESI = 0x1, 0x2, 0x4, 0x8, 0x10, 0x20
OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x1, 0x2, 0x8, 0x9, 0xA
MAX_BACKLOG = 4 << 20      # bytes queued for a slow client before its frames are dropped
# The reference server runs two threads per client; with CPython's default 5 ms GIL
# switch interval a thread woken by a frame can wait milliseconds for the GIL.
SWITCH_INTERVAL_S = 5e-5

log = logging.getLogger("bench.bus.hub")


@dataclass(eq=False)
class Client:
    """One WebSocket connection."""
    sock: socket.socket
    addr: str
    inbuf: bytearray = field(default_factory=bytearray)
    outbuf: bytearray = field(default_factory=bytearray)
    upgraded: bool = False
    ready: bool = False          # bus_request answered
    binary: bool = True          # can.binary+json.v1 (else can.json.v1)
    own: bool = False            # receive_own_messages
    filters: list[tuple[int, int, bool | None]] = field(default_factory=list)
    dropped: int = 0
    closing: bool = False
    events: int = selectors.EVENT_READ
    periodic: dict[int, tuple[float, float, float | None, bytes, dict]] = field(
        default_factory=dict)

    def wants(self, can_id: int, ext: bool) -> bool:
        if not self.filters:
            return True
        for fid, mask, fext in self.filters:
            if (can_id & mask) == (fid & mask) and (fext is None or fext == ext):
                return True
        return False


def _ws_frame(opcode: int, payload: bytes) -> bytes:
    n = len(payload)
    if n <= 125:
        head = bytes((0x80 | opcode, n))
    elif n <= 0xFFFF:
        head = bytes((0x80 | opcode, 126)) + struct.pack(">H", n)
    else:
        head = bytes((0x80 | opcode, 127)) + struct.pack(">Q", n)
    return head + payload


def _parse_frame(buf: bytearray) -> tuple[int, bytes, int] | None:
    """(opcode, unmasked payload, bytes used) of the first complete frame, else None."""
    if len(buf) < 2:
        return None
    b1, b2 = buf[0], buf[1]
    n = b2 & 0x7F
    pos = 2
    if n == 126:
        if len(buf) < 4:
            return None
        n = struct.unpack_from(">H", buf, 2)[0]
        pos = 4
    elif n == 127:
        if len(buf) < 10:
            return None
        n = struct.unpack_from(">Q", buf, 2)[0]
        pos = 10
    masked = b2 & 0x80
    if masked:
        if len(buf) < pos + 4:
            return None
        mask = bytes(buf[pos:pos + 4])
        pos += 4
    if len(buf) < pos + n:
        return None
    data = bytes(buf[pos:pos + n])
    if masked and n:
        m = (mask * (n // 4 + 1))[:n]
        data = (int.from_bytes(data, "big") ^ int.from_bytes(m, "big")).to_bytes(n, "big")
    return b1 & 0x0F, data, pos + n


class SelectHub:
    """Single-threaded python-can-remote-compatible hub (see module docstring)."""

    def __init__(self, host: str = LOOPBACK_HOST, port: int = 0) -> None:
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, port))
        self.listener.listen(16)
        self.listener.setblocking(False)
        self.port = self.listener.getsockname()[1]
        self.sel = selectors.DefaultSelector()
        self.sel.register(self.listener, selectors.EVENT_READ, None)
        self.clients: dict[int, Client] = {}
        self._dirty: set[Client] = set()
        self.frames_forwarded = 0

    # -- plumbing -----------------------------------------------------------------------
    def _accept(self) -> None:
        try:
            sock, addr = self.listener.accept()
        except OSError:
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        c = Client(sock, f"{addr[0]}:{addr[1]}")
        self.clients[sock.fileno()] = c
        self.sel.register(sock, selectors.EVENT_READ, c)

    def _drop(self, c: Client) -> None:
        fd = c.sock.fileno()
        if fd in self.clients:
            del self.clients[fd]
            try:
                self.sel.unregister(c.sock)
            except (KeyError, ValueError):
                pass
        try:
            c.sock.close()
        except OSError:
            pass

    def _write(self, c: Client, data: bytes) -> None:
        """Queue `data` for `c`; queues are flushed once per loop turn (one send per
        client for all the frames of that turn: fewer syscalls and wake-ups)."""
        if len(c.outbuf) > MAX_BACKLOG:
            c.dropped += 1
            return
        c.outbuf += data
        self._dirty.add(c)

    def _flush(self, c: Client) -> None:
        if not c.outbuf or c.closing:
            return
        try:
            sent = c.sock.send(c.outbuf)
        except BlockingIOError:
            sent = 0
        except OSError:
            c.closing = True
            return
        del c.outbuf[:sent]
        want = selectors.EVENT_READ | (selectors.EVENT_WRITE if c.outbuf else 0)
        if want != c.events:
            self.sel.modify(c.sock, want, c)
            c.events = want

    # -- protocol -----------------------------------------------------------------------
    def _handshake(self, c: Client) -> bool:
        end = c.inbuf.find(b"\r\n\r\n")
        if end < 0:
            if len(c.inbuf) > 16384:
                c.closing = True
            return False
        head = bytes(c.inbuf[:end]).decode("latin-1").split("\r\n")
        del c.inbuf[:end + 4]
        headers = {}
        for line in head[1:]:
            k, _, v = line.partition(":")
            headers[k.strip().lower()] = v.strip()
        key = headers.get("sec-websocket-key")
        if headers.get("upgrade", "").lower() != "websocket" or not key:
            self._write(c, b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
            self._flush(c)
            c.closing = True
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

    def _event(self, c: Client, text: str) -> None:
        try:
            ev = json.loads(text)
            kind, payload = ev["type"], ev.get("payload")
        except (ValueError, KeyError, TypeError):
            self._send_json(c, "error", "malformed event")
            return
        if kind == "bus_request":
            cfg = (payload or {}).get("config", {}) if isinstance(payload, dict) else {}
            c.own = bool(cfg.get("receive_own_messages", False))
            for f in cfg.get("can_filters") or []:
                try:
                    c.filters.append((int(f["can_id"]), int(f["can_mask"]),
                                      f.get("extended")))
                except (KeyError, TypeError, ValueError):
                    pass
            c.ready = True
            self._send_json(c, "bus_response",
                            {"channel_info": f"Loopback hub channel {CHANNEL}"})
        elif kind == "message" and isinstance(payload, dict):
            self._forward_json(c, payload)
        elif kind == "periodic_start" and isinstance(payload, dict):
            msg = payload.get("msg", {})
            cid = int(msg.get("arbitration_id", 0))
            period = float(payload.get("period", 0.1))
            dur = payload.get("duration")
            end = None if dur is None else time.monotonic() + float(dur)
            c.periodic[cid] = (period, time.monotonic(), end, b"", msg)
        elif kind == "periodic_stop":
            try:
                c.periodic.pop(int(payload), None)
            except (TypeError, ValueError):
                pass

    def _send_json(self, c: Client, kind: str, payload) -> None:
        self._write(c, _ws_frame(OP_TEXT, json.dumps({"type": kind,
                                                      "payload": payload}).encode()))

    def _forward_json(self, src: Client, m: dict) -> None:
        try:
            data = bytes(m.get("data", []))
            flags = ((F_EXT if m.get("is_extended_id", True) else 0)
                     | (F_RTR if m.get("is_remote_frame") else 0)
                     | (F_ERR if m.get("is_error_frame") else 0)
                     | (F_FD if m.get("is_fd") else 0)
                     | (F_BRS if m.get("bitrate_switch") else 0)
                     | (F_ESI if m.get("error_state_indicator") else 0))
            self._forward(src, int(m["arbitration_id"]), int(m.get("dlc", len(data))),
                          flags, data)
        except (KeyError, TypeError, ValueError):
            self._send_json(src, "error", "malformed message")

    def _forward(self, src: Client | None, can_id: int, dlc: int, flags: int,
                 data: bytes) -> None:
        """Deliver one CAN frame to every client that should see it."""
        ts = time.time()
        ext = bool(flags & F_EXT)
        binary = json_frame = None
        self.frames_forwarded += 1
        for c in list(self.clients.values()):
            if not c.ready or c.closing or (c is src and not c.own):
                continue
            if not c.wants(can_id, ext):
                continue
            if c.binary:
                if binary is None:
                    binary = _ws_frame(OP_BINARY, bytes((BINARY_TYPE,)) + BINARY_MSG.pack(
                        ts, can_id, dlc, flags) + data)
                self._write(c, binary)
            else:
                if json_frame is None:
                    json_frame = _ws_frame(OP_TEXT, json.dumps({"type": "message", "payload": {
                        "timestamp": ts, "arbitration_id": can_id, "is_extended_id": ext,
                        "is_remote_frame": bool(flags & F_RTR),
                        "is_error_frame": bool(flags & F_ERR), "dlc": dlc,
                        "data": list(data)}}).encode())
                self._write(c, json_frame)

    def _read(self, c: Client) -> None:
        try:
            chunk = c.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            c.closing = True
            return
        if not chunk:
            c.closing = True
            return
        c.inbuf += chunk
        if not c.upgraded and not self._handshake(c):
            return
        while True:
            got = _parse_frame(c.inbuf)
            if got is None:
                return
            op, payload, used = got
            del c.inbuf[:used]
            if op == OP_BINARY:
                if c.ready and len(payload) >= 1 + BINARY_MSG.size and \
                        payload[0] == BINARY_TYPE:
                    _, can_id, dlc, flags = BINARY_MSG.unpack_from(payload, 1)
                    self._forward(c, can_id, dlc, flags, payload[1 + BINARY_MSG.size:])
            elif op == OP_TEXT:
                self._event(c, payload.decode("utf-8", "replace"))
            elif op == OP_PING:
                self._write(c, _ws_frame(OP_PONG, payload))
            elif op == OP_CLOSE:
                self._write(c, _ws_frame(OP_CLOSE, payload[:2]))
                self._flush(c)
                c.closing = True
                return

    def _periodic(self) -> float:
        now = time.monotonic()
        nxt = 0.5
        for c in list(self.clients.values()):
            for cid, (period, due, end, _, msg) in list(c.periodic.items()):
                if end is not None and now >= end:
                    del c.periodic[cid]
                    continue
                if now >= due:
                    self._forward_json(c, msg)
                    due = due + period if due + period > now else now + period
                    c.periodic[cid] = (period, due, end, b"", msg)
                nxt = min(nxt, due - now)
        return max(nxt, 0.0)

    def serve(self, stop: threading.Event, parent_pid: int | None = None) -> None:
        next_check = time.monotonic() + 0.2
        while not stop.is_set():
            timeout = min(self._periodic(), 0.2)
            for key, mask in self.sel.select(timeout):
                c = key.data
                if c is None:
                    self._accept()
                    continue
                if mask & selectors.EVENT_READ:
                    self._read(c)
                if mask & selectors.EVENT_WRITE:
                    self._dirty.add(c)
            for c in self._dirty:
                self._flush(c)
            self._dirty.clear()
            for c in [c for c in self.clients.values() if c.closing]:
                self._drop(c)
            now = time.monotonic()
            if now >= next_check:
                next_check = now + 0.2
                if parent_pid and not pid_alive(parent_pid):
                    break
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
    try:
        return serve(args.port, state=not args.no_state, parent_pid=args.parent_pid,
                     server=args.server)
    except OSError as exc:
        print(f"error: cannot start the hub: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
