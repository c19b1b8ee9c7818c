"""SIGINT/SIGTERM handling of a bus run."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from bench.ecu.errors import Interrupted
from bench.runtime import interrupts


class StopSignal:
    """SIGINT/SIGTERM for a bus run. Outside the control loop a signal raises
    `Interrupted` at once; inside it (`defer` set) it only records `signum`, which the
    loop checks every period, so a signal never cuts a frame, the log or the trace."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.signum: int | None = None
        self.defer = False

    def _handler(self, signum: int, frame: Any) -> None:  # noqa: ARG002
        self.signum = signum
        if not self.defer:
            raise Interrupted(signum)

    @contextmanager
    def installed(self) -> Iterator[StopSignal]:
        """Handle SIGINT and SIGTERM here for the duration of the block."""
        old = {s: signal.signal(s, self._handler) for s in self.SIGNALS}
        try:
            if interrupts.pending():    # a Ctrl-C lost in an import: stop before the run
                self._handler(signal.SIGINT, None)
            yield self
        finally:
            for s, h in old.items():
                signal.signal(s, h)
