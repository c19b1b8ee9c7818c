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

The state directory (`state_dir`) is ``$BENCH_STATE_DIR``, else
``$XDG_RUNTIME_DIR/ema-bench``, else a per-user directory under the temporary directory
(``ema-bench-UID``, 0700), the same from every working directory. This module is shared by the plant process and the bench (`bench.bus`).
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import stat
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import can

STATE_ENV = "BENCH_STATE_DIR"
HUB_FILE = "hub.json"
PLANT_FILE = "plant.json"
LOOPBACK_HOST = "127.0.0.1"


class BusUnavailable(RuntimeError):
    """No bus is configured or the configured one cannot be opened."""


STATE_NAME = "ema-bench"


def state_dir() -> Path:
    """The one state directory of this user's bench, whatever the working directory:
    ``$BENCH_STATE_DIR``, else ``$XDG_RUNTIME_DIR/ema-bench``, else
    ``TMPDIR/ema-bench-UID`` (the temporary directory's, created 0700 and used only
    when it is this user's own directory, not a link, closed to others), else
    ``~/.cache/ema-bench``. The first three are gone at a reboot, as the processes
    they name; a record that outlived its process is recognised as stale anyway."""
    env = os.environ.get(STATE_ENV)
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and Path(xdg).is_dir():
        return Path(xdg) / STATE_NAME
    uid = os.getuid() if hasattr(os, "getuid") else 0
    tmp = Path(tempfile.gettempdir()) / f"{STATE_NAME}-{uid}"
    if _own_private_dir(tmp):
        return tmp
    return Path.home() / ".cache" / STATE_NAME


def _own_private_dir(path: Path) -> bool:
    """Create `path` (mode 0700) if it is missing; True when it is a directory (not a
    link) owned by this user and closed to others, as a shared temporary directory
    requires (anyone may have created the name first)."""
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    except OSError:
        return False
    try:
        st = os.lstat(path)
    except OSError:
        return False
    uid = os.getuid() if hasattr(os, "getuid") else st.st_uid
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != uid:
        return False
    if st.st_mode & 0o077:
        try:
            os.chmod(path, 0o700)
        except OSError:
            return False
    return True


def _make_state_dir(d: Path) -> None:
    """The state directory, created (0700: it holds pids and the hub's port)."""
    d.mkdir(mode=0o700, parents=True, exist_ok=True)


# -- state records -------------------------------------------------------------------------
# A record names its process by pid and by an identity token written at start (boot id and
# start time, /proc/PID/stat field 22), so a pid reused by another process after a crash is
# recognised as stale. Records without a token (written by hand or by an older bench) are
# accepted only when the process's command line is the bench's (ROLES).
ROLES = {HUB_FILE: ("hub", "bench.bus.hub"), PLANT_FILE: ("plant", "plant_rt")}
LOCK_FILE = "lock"
_reported: set[str] = set()


class StateError(ValueError):
    """A state record that is not what the bench writes (corrupt)."""


def valid_pid(value: Any) -> int:
    """`value` as a pid a record may name: an int above 1 (never init, never a group);
    StateError for a bool, float, string, 0, 1 or a negative number."""
    if type(value) is not int or value <= 1:
        raise StateError(f"pid {value!r} is not a process id")
    return value


def _check_record(name: str, data: Any) -> dict[str, Any]:
    """The record `data` of state file `name` with its types checked (StateError if not)."""
    if not isinstance(data, dict):
        raise StateError(f"not a JSON object but {type(data).__name__}")
    if "pid" not in data:
        raise StateError("no pid")
    valid_pid(data["pid"])
    if "start" in data and not isinstance(data["start"], str):
        raise StateError(f"start token {data['start']!r} is not a string")
    if name == HUB_FILE:
        port = data.get("port")
        if type(port) is not int or not 0 < port < 65536:
            raise StateError(f"port {port!r} is not a TCP port")
    elif name == PLANT_FILE:
        for key in ("bus", "log", "source", "pace"):
            if (key in data or key == "bus") and not isinstance(data.get(key), str):
                raise StateError(f"{key} {data.get(key)!r} is not a string")
    return data


def _proc_stat(pid: int) -> list[str] | None:
    """Fields 3.. of /proc/PID/stat (after the command name), or None."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[-1].split()
    except OSError:
        return None


def process_token(pid: int) -> str | None:
    """An identity of process `pid` that a reused pid does not share: "BOOT_ID:START",
    START its start time in clock ticks after boot (/proc/PID/stat field 22); None when
    the process does not exist or the system has no /proc."""
    fields = _proc_stat(pid)
    if fields is None or len(fields) < 20:
        return None
    try:
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        boot = "-"
    return f"{boot}:{fields[19]}"


def process_cmdline(pid: int) -> str:
    """The command line of process `pid`, arguments joined by spaces ("" if unknown)."""
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return ""
    return raw.replace(b"\0", b" ").decode(errors="replace").strip()


def is_process(pid: Any, token: str | None = None, module: str | None = None) -> bool:
    """True when `pid` is a live process and the one meant: its identity token equals
    `token` when one is given, else its command line names `module` (`python -m MODULE`).
    With neither, False: nothing unidentified is ever the bench's."""
    try:
        valid_pid(pid)
    except StateError:
        return False
    if not pid_alive(pid):
        return False
    if token:
        return process_token(pid) == token
    if module:
        return module in process_cmdline(pid).split()
    return False


def _report(path: Path, message: str) -> None:
    """One line on stderr per stale or corrupt state file and process."""
    key = f"{path}:{message}"
    if key not in _reported:
        _reported.add(key)
        print(message, file=sys.stderr, flush=True)


def _discard(path: Path, raw: bytes) -> str:
    """Remove state file `path` if it still holds `raw` (a fresh record written meanwhile
    is kept); returns what was done, for the message."""
    try:
        if path.read_bytes() == raw:
            path.unlink()
        return "removed"
    except FileNotFoundError:
        return "removed"
    except OSError as exc:
        return f"ignored (cannot remove it: {exc.strerror})"


def read_state(name: str) -> dict[str, Any] | None:
    """The state record `name` (hub.json, plant.json) if its process is the one it names,
    else None. A corrupt record (not JSON, not an object, wrong types) or a stale one (its
    pid not running, or running another program) is reported in one line on stderr,
    removed, and treated as absent."""
    path = state_dir() / name
    try:
        raw = path.read_bytes()
    except OSError:
        return None
    try:
        data = _check_record(name, json.loads(raw))
    except (ValueError, RecursionError) as exc:   # StateError, JSON and UTF-8 errors
        why = exc if isinstance(exc, StateError) else "not JSON"
        _report(path, f"corrupt state file {path} ({why}): {_discard(path, raw)}")
        return None
    pid = data["pid"]
    role, module = ROLES.get(name, (Path(name).stem, None))
    if not is_process(pid, data.get("start"), module):
        why = (f"pid {pid} is not running" if not pid_alive(pid)
               else f"pid {pid} is not the bench's {role}")
        _report(path, f"stale state file {path} ({why}): {_discard(path, raw)}")
        return None
    return data


def write_state(name: str, data: dict[str, Any]) -> Path:
    """Write a state record atomically; a record naming a pid gets that process's
    identity token ("start") unless it has one."""
    d = state_dir()
    _make_state_dir(d)
    path = d / name
    if "pid" in data and "start" not in data:
        token = process_token(data["pid"])
        if token:
            data = {**data, "start": token}
    tmp = path.with_name(f".{name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=2))
    tmp.replace(path)
    return path


def remove_state(name: str, pid: int | None = None) -> None:
    """Remove a state record (only if it still belongs to `pid`, when given)."""
    path = state_dir() / name
    try:
        if pid is not None:
            data = json.loads(path.read_text())
            if not isinstance(data, dict) or data.get("pid") != pid:
                return
        path.unlink()
    except (OSError, ValueError):
        pass


class StateLocked(RuntimeError):
    """Another bench command holds the state directory's lock for too long."""


@contextmanager
def state_lock(timeout: float = 120.0, on_wait: Callable[[], None] | None = None):
    """Hold the state directory's lock (flock on its `lock` file) for a check-and-start
    or a stop. Waits up to `timeout` s (calling `on_wait` once if it has to wait), then
    raises StateLocked. The lock goes with the process: a crashed holder frees it."""
    d = state_dir()
    _make_state_dir(d)
    fd = os.open(d / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o600)   # not inherited
    try:
        end = time.monotonic() + timeout
        waited = False
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if not waited and on_wait is not None:
                    on_wait()
                waited = True
                if time.monotonic() >= end:
                    raise StateLocked(f"another bench command has held {d / LOCK_FILE} for "
                                      f"{timeout:g} s") from None
                time.sleep(0.05)
        yield
    finally:
        os.close(fd)


def pid_alive(pid: Any) -> bool:
    """True when `pid` (an int) names a live process that is not a zombie."""
    if type(pid) is not int or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    fields = _proc_stat(pid)          # a zombie child is not alive
    return fields is None or fields[0] != "Z"


def port_open(host: str, port: int, timeout: float = 0.5) -> bool:
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def hub_label(state: Path | None = None) -> str:
    """Where a loopback hub recorded in the state directory comes from, for messages:
    which bench a command talks to."""
    return f"loopback hub of the bench in {state or state_dir()}"


def hub_url() -> str | None:
    """The URL of a running loopback hub from the state directory, if any."""
    st = read_state(HUB_FILE)
    if not st:
        return None
    port = st["port"]
    if port_open(LOOPBACK_HOST, port):
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
            return {**extra, "interface": "remote", "channel": url}, hub_label()
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
    """Shut a bus down without ever blocking longer than about `timeout`, and leave it
    shut down whatever happened to its server.

    python-can's `BusABC.__del__` calls `shutdown()` again on any bus not marked shut
    down, which after a failed first shutdown (a killed hub: python-can-remote's close
    handshake raises on the dead socket) printed "RemoteBus was not properly shut down"
    and a traceback at exit. So: a shutdown that raises or hangs (a hung server never
    answers the close handshake) ends the connection under it, and the bus is then
    marked shut down the way `BusABC.shutdown` does it."""
    if bus is None:
        return
    th = threading.Thread(target=_quiet_shutdown, args=(bus,), daemon=True, name="close-bus")
    th.start()
    th.join(timeout)
    if th.is_alive():                 # hung: end the connection the shutdown waits on
        _end_connection(bus, close=False)
        th.join(min(timeout, 0.5))
    if not th.is_alive():
        _end_connection(bus, close=True)
    _mark_shut_down(bus)


def _quiet_shutdown(bus: can.BusABC) -> None:
    try:
        bus.shutdown()
    except Exception:  # noqa: BLE001 - closing a dead connection is not an error
        _end_connection(bus, close=True)


def _end_connection(bus: can.BusABC, close: bool) -> None:
    """Shut down (and close, when `close`) the bus's network socket, if it has one."""
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket) or sock.fileno() < 0:
        return
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    if close:
        sock.close()


def _mark_shut_down(bus: can.BusABC) -> None:
    """Record a bus whose own shutdown failed as shut down (`BusABC.shutdown`: stop its
    periodic tasks, set the flag), so `__del__` does not try again."""
    if getattr(bus, "_is_shutdown", True):
        return
    try:
        can.BusABC.shutdown(bus)          # type: ignore[arg-type]
    except Exception:  # noqa: BLE001 - periodic tasks of a dead connection
        pass
    bus._is_shutdown = True
