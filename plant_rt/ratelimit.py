"""Rate limits on a caller's clock: the CiA 301 EMCY inhibit time (`Inhibit`, object
0x1015) and a log-line limiter (`LogLimiter`). Both take the time as an argument, so the
plant node runs them on its node clock (SYNC time in lockstep, see `plant_rt.node`)."""

from __future__ import annotations

import logging
import math
import sys

EPS_S = 1e-9        # node-clock comparisons: SYNC time is a sum of float periods


class Inhibit:
    """At most one event per `inhibit_s` of a caller's clock (CiA 301 EMCY inhibit time).

    An event that comes within the inhibit time waits; a later one with the same key
    replaces it (its latest state is what is sent, the repeat is counted), events with
    distinct keys wait in the order of their latest occurrence. Nothing is lost but
    repeats, and the queue holds at most one event per key. `inhibit_s` 0: no limit."""

    def __init__(self, inhibit_s: float) -> None:
        self.inhibit_s = inhibit_s
        self.last_s = -math.inf                  # when the last event was released (s)
        self.pending: dict[object, list] = {}    # key -> [payload, repeats suppressed]

    def add(self, key: object, payload: object) -> bool:
        """Queue an event; True when it replaced a waiting one of the same key."""
        old = self.pending.pop(key, None)
        self.pending[key] = [payload, old[1] + 1 if old else 0]
        return old is not None

    def next_s(self) -> float:
        """When the next event may be released (s of the caller's clock)."""
        return self.last_s + self.inhibit_s

    def due(self, now_s: float) -> list[tuple[object, int]]:
        """The events to release at `now_s`: (payload, repeats it replaced)."""
        out = []
        while self.pending and now_s >= self.next_s() - EPS_S:
            key = next(iter(self.pending))
            payload, repeats = self.pending.pop(key)
            out.append((payload, repeats))
            self.last_s = now_s
        return out

    def drain(self) -> list[tuple[object, int]]:
        """Every waiting event, at once (a reset); the inhibit time starts afresh."""
        out = [(payload, repeats) for payload, repeats in self.pending.values()]
        self.pending.clear()
        self.last_s = -math.inf
        return out


class LogLimiter:
    """python logging with at most one line per message (its format string) per window of
    a caller's clock (s): lines within the window are not written but counted; when the
    window ends (`flush`) the latest is written with the count of the others, so a flood
    gives one line per window and says how many it stands for."""

    def __init__(self, logger: logging.Logger, window_s: float) -> None:
        self.logger = logger
        self.window_s = window_s
        self._lines: dict[str, list] = {}   # fmt -> [last written (s), suppressed, args, kw]
        self._held = 0                      # messages with suppressed lines

    def log(self, now_s: float, level: int, fmt: str, *args: object, **kw: object) -> None:
        """`logger.log(level, fmt, *args, **kw)` unless a line of `fmt` was written less
        than the window ago (exc_info=True is captured now, for a later write)."""
        if not self.logger.isEnabledFor(level):
            return
        if kw.get("exc_info") is True:
            kw["exc_info"] = sys.exc_info()
        e = self._lines.get(fmt)
        if e is not None and now_s < e[0] + self.window_s - EPS_S:
            self._held += e[1] == 0
            e[1] += 1
            e[2], e[3] = (level, args), kw
            return
        if e is not None and e[1]:
            self._held -= 1
        self._write(fmt, level, args, kw, e[1] if e else 0)
        self._lines[fmt] = [now_s, 0, (level, args), kw]

    def flush(self, now_s: float) -> None:
        """Write the latest suppressed line of every message whose window has ended."""
        if not self._held:
            return
        for fmt, e in self._lines.items():
            if e[1] and now_s >= e[0] + self.window_s - EPS_S:
                (level, args), kw = e[2], e[3]
                self._write(fmt, level, args, kw, e[1] - 1)   # the latest is written
                e[0], e[1] = now_s, 0
                self._held -= 1

    def _write(self, fmt: str, level: int, args: tuple, kw: dict, suppressed: int) -> None:
        if suppressed:
            fmt += " [%d similar lines suppressed]"
            args = (*args, suppressed)
        self.logger.log(level, fmt, *args, **kw)


__all__ = ["EPS_S", "Inhibit", "LogLimiter"]
