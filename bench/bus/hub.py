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

One client cannot stop the select hub or take the bus from the others:

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
import gc
import logging
import os
import signal
import sys
import threading

from bench.bus.selecthub import SWITCH_INTERVAL_S, SelectHub
from bench.bus.wsproto import CHANNEL
from ema_contract.transport import HUB_FILE, LOOPBACK_HOST, pid_alive, remove_state, write_state


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
