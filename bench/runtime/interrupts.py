"""Ctrl-C that a library swallowed.

A SIGINT that lands while `bench` is still importing its libraries can be lost: one of
them catches the KeyboardInterrupt in a broad `except` during its import (measured:
a Ctrl-C 0.5 s after `bench log` started, inside python-can's import of its
MF4 support, was swallowed, and the command went on recording until a second Ctrl-C;
python-can's own `can.logger` does the same). `counting` (around `bench.cli.main`)
counts every SIGINT and then raises KeyboardInterrupt as Python's own handler does; a
command that installs its own handler for a long loop asks `pending()` first and stops at
once when one was lost on the way."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

_received = 0


def _handler(signum: int, frame: Any) -> None:  # noqa: ARG001
    global _received
    _received += 1
    raise KeyboardInterrupt


@contextmanager
def counting() -> Iterator[None]:
    """Count SIGINTs inside the block (main thread, over Python's default handler only;
    else nothing changes), then put the handler back and forget the count."""
    global _received
    _received = 0
    mine = (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler)
    if mine:
        signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        if mine:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        _received = 0


def pending() -> bool:
    """True when a SIGINT arrived inside `counting` (whether or not anyone caught it)."""
    return _received > 0
