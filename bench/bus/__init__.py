"""The bench's side of the CAN bus: transport selection, loopback hub, logs.

The only thing the bench holds is a python-can ``BusABC``; which one comes from
ordinary python-can configuration (see `ema_contract.transport` for the precedence: flags,
``can.rc``/environment/config file, vcan0, the loopback hub of `bench up`). When none
is found, commands that need a bus start a private loopback hub for their own run.

- `bench.bus.hub`: the loopback hub (python-can-remote on 127.0.0.1),
- `bench.bus.procs`: starting/stopping hub and plant processes,
- `bench.bus.logs`: candump logs: tolerant reading, replay, decoding to a `Trace`.
"""

from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from bench import BenchError, refuse_mf4_import

HUB_MODULE = "bench.bus.hub"


def started_as(module: str, argv: list[str] | None = None) -> bool:
    """Whether this process is `python -m MODULE` (its original command line)."""
    argv = list(sys.orig_argv if argv is None else argv)
    return any((a == "-m" and b == module) for a, b in zip(argv, argv[1:], strict=False)) or \
        f"-m{module}" in argv


# the hub process (`python -m bench.bus.hub`, started by `bench up` and by every command
# that runs on a private bus) writes no log file: no MF4 support to import there
if started_as(HUB_MODULE):
    refuse_mf4_import()

import can  # noqa: E402
import can.cli  # noqa: E402

from ema_contract.transport import (  # noqa: E402
    BusUnavailable,
    close_bus,
    describe,
    open_bus,
    resolve,
    state_dir,
)

BUS_KEYS = ("interface", "channel", "bitrate", "fd", "data_bitrate", "timing")


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """python-can's own bus flags (-i/-c/-b/--fd/--bus-kwargs ...), as every
    python-can tool accepts them."""
    can.cli.add_bus_arguments(parser)


def bus_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The bus settings given on the command line (only those given)."""
    cfg: dict[str, Any] = {k: getattr(args, k) for k in BUS_KEYS if k in args}
    cfg.update(getattr(args, "bus_kwargs", None) or {})
    return cfg


def find_bus(settings: dict[str, Any] | None = None) -> tuple[dict[str, Any], str] | None:
    """(bus config, source) from configuration, vcan0 or a running hub; None if none."""
    try:
        return resolve(settings or {})
    except BusUnavailable as exc:
        raise BenchError(str(exc)) from None


def is_simulated(cfg: dict[str, Any]) -> bool:
    """True for buses where no real actuator can be (the loopback hub, virtual, vcan)."""
    iface = str(cfg.get("interface", ""))
    chan = str(cfg.get("channel", ""))
    return (iface == "virtual" or (iface == "remote" and chan.startswith("ws://127.0.0.1"))
            or (iface == "socketcan" and chan.startswith("vcan")))


def connect(cfg: dict[str, Any], receive_own_messages: bool = False,
            timeout: float = 5.0) -> can.BusABC:
    """Open the bus `cfg` (BenchError with the reason if it cannot be opened)."""
    try:
        return open_bus(cfg, timeout=timeout, receive_own_messages=receive_own_messages)
    except BusUnavailable as exc:
        raise BenchError(str(exc)) from None


@dataclass
class BusSession:
    """A bus for one command, with whatever the bench had to start for it."""
    cfg: dict[str, Any]
    source: str
    children: list = field(default_factory=list)

    @property
    def description(self) -> str:
        return f"{describe(self.cfg)} ({self.source})"

    def logs(self) -> list[str]:
        """The logs of the processes started for this command."""
        return [str(c.log_path) for c in self.children
                if getattr(c, "ephemeral", False) and c.log_path is not None]

    def close(self, keep_logs: bool = False) -> None:
        """Stop what was started for this command; remove its logs unless `keep_logs`."""
        for child in reversed(self.children):
            child.stop()
            if not keep_logs:
                child.remove_log()
        self.children.clear()


@contextmanager
def session(settings: dict[str, Any] | None = None, start_hub: bool = True):
    """Yield a `BusSession`: the configured bus, else a private loopback hub started
    for this command (stopped on exit).

    The logs of what was started for the command (in `bench.bus.procs.run_dir()`) are
    removed when it ends well; when it fails they are kept and the error names them."""
    from bench.bus.procs import start_hub as _start_hub

    found = find_bus(settings)
    sess: BusSession
    if found is not None:
        sess = BusSession(*found)
    elif start_hub:
        hub = _start_hub(persistent=False)
        sess = BusSession({**(settings or {}), "interface": "remote",
                           "channel": hub.info["url"]},
                          f"private loopback hub for this command: no `bench up` in "
                          f"{state_dir()}", [hub])
    else:
        raise BenchError("no CAN bus: bench is not up (no loopback hub running), there is "
                         "no vcan0 and no python-can configuration (-i/-c, CAN_INTERFACE, "
                         "~/.canrc); run `bench up` first")
    failed = False
    try:
        yield sess
    except Exception as exc:
        failed = True
        logs = sess.logs()
        if logs:
            where = f"logs of the processes started for this command: {', '.join(logs)}"
            if isinstance(exc, BenchError) and len(exc.args) == 1:
                exc.args = (f"{exc}; {where}",)
            else:
                print(where, file=sys.stderr)
        raise
    finally:
        sess.close(keep_logs=failed)


__all__ = ["add_bus_arguments", "bus_settings", "find_bus", "connect", "close_bus",
           "session", "BusSession", "is_simulated"]
