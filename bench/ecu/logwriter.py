"""The ECU's log writer: python-can's `can.Logger` (candump ``.log`` by default; the suffix
picks ``.asc``, ``.blf``, ``.trc``, ``.mf4``: `bench.bus.logwrite`)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import can

from bench.bus.logwrite import flush, open_writer
from bench.ecu.errors import LogWriteError


class _Log(can.Listener):
    """Every frame into a log (python-can's writer for the path's suffix, `can.Logger`).

    A write that fails (disk full, file too large) is kept in `error` and ends the
    logging, never the thread that delivered the frame: the ECU reports it
    (`raise_error`) at its next check instead of losing its receive thread."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.writer = open_writer(self.path)
        self.count = 0
        self.error: Exception | None = None
        self.closed = False
        self._last_flush = time.monotonic()
        self._lock = threading.Lock()     # set-up: notifier thread and main thread

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            if self.error is not None or self.closed:
                return
            try:
                self.writer.on_message_received(msg)
                self.count += 1
                now = time.monotonic()
                if now - self._last_flush > 0.5:
                    flush(self.writer)
                    self._last_flush = now
            except (OSError, ValueError) as exc:
                self.error = exc

    def raise_error(self, where: str = "") -> None:
        """LogWriteError if a write has failed (`where`: when, for the message)."""
        exc = self.error
        if exc is not None:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            raise LogWriteError(f"cannot write the log {self.path}: {reason}{where}")

    def close(self) -> None:
        """Flush and close; a failing last flush is kept in `error` like any write."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            try:
                self.writer.stop()
            except (OSError, ValueError) as exc:
                if self.error is None:
                    self.error = exc
                try:
                    fh = getattr(self.writer, "file", None)
                    if fh is not None:
                        fh.close()
                except (OSError, ValueError):
                    pass
            except Exception:  # noqa: BLE001 - closing must not mask the run's error
                pass
