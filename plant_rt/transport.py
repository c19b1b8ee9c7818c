"""Which CAN bus to open: ordinary python-can configuration, else vcan0, else the loopback hub.

Precedence (the first that names an interface wins):

1. explicit settings (command-line flags ``-i/-c/-b/--bus-kwargs``, python-can's
   ``can.cli.add_bus_arguments``),
2. python-can's own configuration: ``can.rc``, the environment (``CAN_INTERFACE``,
   ``CAN_CHANNEL``, ``CAN_BITRATE``, ``CAN_CONFIG``) and its config file
   (``~/.canrc``, ``~/.can``, ``/etc/can.conf``), through ``can.util.load_config``,
3. ``socketcan`` on ``vcan0`` when the kernel has SocketCAN and the interface is up,
4. the loopback hub a bench started (python-can-remote on 127.0.0.1, recorded in the
   state directory), as ``interface=remote, channel=ws://127.0.0.1:PORT/``.

The state directory is ``$BENCH_STATE_DIR``, else ``$XDG_RUNTIME_DIR/ema-bench``, else
``./.bench``. This module is shared by the plant process and the bench (`bench.bus`).
"""

from __future__ import annotations

import json
import os
import socket
import threading
from pathlib import Path
from typing import Any

import can

STATE_ENV = "BENCH_STATE_DIR"
HUB_FILE = "hub.json"
PLANT_FILE = "plant.json"
LOOPBACK_HOST = "127.0.0.1"


class BusUnavailable(RuntimeError):
    """No bus is configured or the configured one cannot be opened."""


def state_dir() -> Path:
    env = os.environ.get(STATE_ENV)
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and Path(xdg).is_dir():
        return Path(xdg) / "ema-bench"
    return Path.cwd() / ".bench"


def read_state(name: str) -> dict[str, Any] | None:
    """A state record (hub.json, plant.json) whose process is still alive, else None."""
    path = state_dir() / name
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not pid_alive(int(data.get("pid", 0))):
        return None
    return data


def write_state(name: str, data: dict[str, Any]) -> Path:
    d = state_dir()
    d.mkdir(parents=True, exist_ok=True)
    path = d / name
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    tmp.replace(path)
    return path


def remove_state(name: str, pid: int | None = None) -> None:
    """Remove a state record (only if it still belongs to `pid`, when given)."""
    path = state_dir() / name
    try:
        if pid is not None and json.loads(path.read_text()).get("pid") != pid:
            return
        path.unlink()
    except (OSError, ValueError):
        pass


def pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a zombie child is not alive
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True


def port_open(host: str, port: int, timeout: float = 0.5) -> bool:
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def hub_url() -> str | None:
    """The URL of a running loopback hub from the state directory, if any."""
    st = read_state(HUB_FILE)
    if not st:
        return None
    port = int(st.get("port", 0))
    if port and port_open(LOOPBACK_HOST, port):
        return f"ws://{LOOPBACK_HOST}:{port}/"
    return None


def socketcan_works(channel: str = "vcan0") -> bool:
    """True when the kernel has SocketCAN and `channel` exists and accepts a raw socket."""
    if not hasattr(socket, "AF_CAN") or not Path(f"/sys/class/net/{channel}").exists():
        return False
    try:
        with socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW) as s:
            s.bind((channel,))
        flags = Path(f"/sys/class/net/{channel}/flags").read_text().strip()
        return bool(int(flags, 16) & 0x1)  # IFF_UP
    except (OSError, ValueError):
        return False


def python_can_config(given: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """python-can's merged configuration (given > can.rc > environment > config file),
    or None when none of them names an interface."""
    given = {k: v for k, v in (given or {}).items() if v is not None}
    try:
        cfg = dict(can.util.load_config(config=given))
    except can.CanInterfaceNotImplementedError as exc:
        if given.get("interface") or os.environ.get("CAN_INTERFACE"):
            raise BusUnavailable(str(exc)) from None
        return None
    return cfg if cfg.get("interface") else None


def resolve(given: dict[str, Any] | None = None, allow_hub: bool = True
            ) -> tuple[dict[str, Any], str] | None:
    """(bus config, where it came from) by the precedence of this module, or None."""
    cfg = python_can_config(given)
    if cfg is not None:
        return cfg, "python-can configuration"
    extra = {k: v for k, v in (given or {}).items() if v is not None}
    if socketcan_works("vcan0"):
        return {**extra, "interface": "socketcan", "channel": "vcan0"}, "socketcan vcan0"
    if allow_hub:
        url = hub_url()
        if url:
            return {**extra, "interface": "remote", "channel": url}, "loopback hub"
    return None


def describe(cfg: dict[str, Any]) -> str:
    return f"{cfg.get('interface')}:{cfg.get('channel')}"


def open_bus(cfg: dict[str, Any], timeout: float = 5.0, **kwargs: Any) -> can.BusABC:
    """`can.Bus(**cfg, **kwargs)` with a time limit (a hung server cannot hang us)."""
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["bus"] = can.Bus(**{**cfg, **kwargs})
        except BaseException as exc:  # noqa: BLE001 - reported below
            box["error"] = exc

    th = threading.Thread(target=target, daemon=True, name="open-bus")
    th.start()
    th.join(timeout)
    if th.is_alive():
        raise BusUnavailable(f"opening the CAN bus {describe(cfg)} timed out after {timeout} s")
    if "error" in box:
        exc = box["error"]
        raise BusUnavailable(f"cannot open the CAN bus {describe(cfg)}: "
                             f"{type(exc).__name__}: {exc}") from exc
    bus = box["bus"]
    sock = getattr(bus, "socket", None)   # python-can-remote: small frames, no Nagle delay
    if isinstance(sock, socket.socket) and sock.family in (socket.AF_INET, socket.AF_INET6):
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError:
            pass
    return bus


def close_bus(bus: can.BusABC | None, timeout: float = 2.0) -> None:
    """Shut a bus down without ever blocking longer than `timeout`."""
    if bus is None:
        return
    th = threading.Thread(target=_quiet_shutdown, args=(bus,), daemon=True, name="close-bus")
    th.start()
    th.join(timeout)


def _quiet_shutdown(bus: can.BusABC) -> None:
    try:
        bus.shutdown()
    except Exception:  # noqa: BLE001 - closing a dead connection is not an error
        pass
