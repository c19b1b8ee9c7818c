"""Closing a bus whose hub died: `close_bus` leaves the bus shut down,
so python-can's `BusABC.__del__` has nothing left to do and prints nothing (it used to
warn "RemoteBus was not properly shut down" and print a traceback of its second
shutdown on a dead socket)."""

from __future__ import annotations

import gc
import logging
import sys
import time

import pytest
from bus_helpers import thread_hub

from ema_contract import transport as T


@pytest.fixture
def hub():
    """A hub in a thread; `kill()` drops every connection at once, as a killed hub does."""
    with thread_hub() as h:
        yield h


@pytest.fixture
def unraisable(monkeypatch):
    """Exceptions raised in __del__ (which Python prints as 'Exception ignored in')."""
    seen: list = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: seen.append(
        f"{u.exc_type.__name__}: {u.exc_value} in {u.object!r}"))
    return seen


@pytest.mark.parametrize("noticed", [True, False], ids=["client-saw-eof", "client-unaware"])
def test_close_bus_after_the_hub_died(hub, unraisable, caplog, noticed):
    bus = T.open_bus({"interface": "remote", "channel": hub.url})
    hub.kill()
    if noticed:                       # the client's next read finds the connection gone
        with pytest.raises(Exception):  # noqa: B017 - python-can-remote's WebsocketClosed
            bus.recv(2.0)
    with caplog.at_level(logging.WARNING, logger="can"):
        t0 = time.monotonic()
        T.close_bus(bus)
        assert time.monotonic() - t0 < 1.0
        T.close_bus(bus)              # twice: harmless
        del bus
        gc.collect()
    assert unraisable == []
    assert "not properly shut down" not in caplog.text


def test_close_bus_of_a_live_hub_is_clean(hub, unraisable, caplog):
    bus = T.open_bus({"interface": "remote", "channel": hub.url})
    with caplog.at_level(logging.WARNING, logger="can"):
        T.close_bus(bus)
        del bus
        gc.collect()
    assert unraisable == [] and "not properly shut down" not in caplog.text


class _Stuck:
    """A bus whose shutdown blocks until its socket is shut down (a hung server)."""

    def __init__(self) -> None:
        import socket
        self.socket, self._peer = socket.socketpair()
        self._is_shutdown = False

    def shutdown(self) -> None:
        self.socket.recv(1)           # returns b"" once the socket is shut down
        self._is_shutdown = True

    def stop_all_periodic_tasks(self) -> None:
        pass


def test_close_bus_of_a_hung_server_ends_within_its_timeout():
    bus = _Stuck()
    t0 = time.monotonic()
    T.close_bus(bus, timeout=0.3)
    assert time.monotonic() - t0 < 1.0
    assert bus._is_shutdown
    bus._peer.close()
    bus.socket.close()
