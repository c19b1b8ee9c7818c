"""The time stamps of the ECU's log: the wall clock, or in lockstep the bus's own time.

A lockstep run goes as fast as the machine allows, so its wall-clock stamps are not the
bus's time: 1,000 SYNC periods of 1 ms spanned 0.611 s, and `cantools plot`,
`canplayer` or `bench replay` saw a distorted timeline. In bus time (`LogClock.start`)
SYNC k of the run is stamped at the run's start plus k periods, and each frame after it
at the end of the frame before it, a classic frame lasting 47 + 8 x (data bytes) bit
times without stuff bits (at `NOMINAL_BITRATE`, the bench's 1 Mbit/s); the frames after
the run follow its last period. Set-up frames keep the wall clock, and stamps never go
back. Stamps are whole microseconds (the candump log's resolution), so the decoded
trace's bus time is k periods exactly."""

from __future__ import annotations

import math
import time

import can

NOMINAL_BITRATE = 1_000_000


class LogClock:
    """Stamps for the frames the ECU records, in the order it records them."""

    def __init__(self) -> None:
        self.bus_time = False
        self._period_us = 0
        self._frame_us = [47.0 + 8.0 * n for n in range(65)]   # at NOMINAL_BITRATE
        self._anchor_us = 0
        self._next_us = 0.0
        self._last_us = 0
        self._last_wall = -math.inf

    def start(self, period_s: float, bitrate: int | None = None) -> None:
        """From now on, bus time: the run's first SYNC at the wall clock's now."""
        self.bus_time = True
        self._period_us = int(round(period_s * 1e6))
        bit_us = 1e6 / (bitrate or NOMINAL_BITRATE)
        self._frame_us = [(47 + 8 * n) * bit_us for n in range(65)]
        now = int(round(time.time() * 1e6))
        after = math.ceil(self._last_wall * 1e6) + 1 if self._last_wall > 0 else 0
        self._anchor_us = max(now, after)
        self._last_us = self._anchor_us - 1
        self._next_us = float(self._anchor_us)

    def period(self, k: int) -> None:
        """Period k of the run begins (its SYNC is the next frame recorded)."""
        if self.bus_time:
            self._next_us = float(self._anchor_us + k * self._period_us)

    def stamp(self, msg: can.Message) -> float:
        """The time stamp (s) of `msg`, recorded now."""
        if not self.bus_time:
            wall = time.time()
            if wall > self._last_wall:
                self._last_wall = wall
            return wall
        t = int(self._next_us + 0.5)
        if t <= self._last_us:
            t = self._last_us + 1
        self._next_us = t + self._frame_us[len(msg.data)]
        self._last_us = t
        return t / 1e6
