"""Wall-clock pacing on absolute deadlines, with lateness statistics.

`RealtimePacer` releases period k at ``t0 + k T`` (``time.perf_counter_ns``), never at
"last release + T", so lateness does not accumulate (as python-can's
``ThreadBasedCyclicSendTask._run``). Waiting is split in two: while more than the spin
window (default 200 us) is left, a caller-supplied ``poll(timeout_s)`` blocks on input
(e.g. ``bus.recv``) so frames are served while waiting; the last ``spin`` is a busy-wait,
which on a 2-core machine brings the p99 lateness from about 120 us (plain sleep) to
below 1 us (docs/bus.md, "Real time on this machine"). Never spin continuously under
SCHED_FIFO: the kernel throttles a real-time task that takes a whole core.

`use_realtime_priority(n)` (the `--rt-priority N` flag of `bench plant`, `bench up`,
`bench run`) puts a process, and the processes it starts afterwards, under SCHED_FIFO.
The pacer's spin is bounded (200 us of each 1 ms period), so a real-time plant uses a
quarter of a core at most and stays far below the throttling limit (95 % of a core by
default). Measured on this 2-vCPU machine (docs/performance.md, Bus): the p99 release
lateness of a real-time bus run falls from ~0.9-1.2 ms to ~0.1 ms with hub, plant and
ECU at SCHED_FIFO 10; without the spin window the same scheduling is worse.

A period is a *deadline miss* when its work finished after the next period's release
(the job overran its period). Lateness (release jitter) is kept in a 1 us histogram up
to 20 ms, so the percentiles are exact to 1 us whatever the run length.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable

import numpy as np

NS = 1_000_000_000


class LatenessStats:
    """Histogram of lateness in 1 us bins (0 .. `max_us`, the last bin holds overflow)."""

    def __init__(self, max_us: int = 20_000) -> None:
        self.hist = np.zeros(max_us + 1, dtype=np.int64)
        self.max_ns = 0
        self.count = 0

    def reset(self) -> None:
        self.hist[:] = 0
        self.max_ns = 0
        self.count = 0

    def add(self, late_ns: int) -> None:
        if late_ns < 0:
            late_ns = 0
        b = late_ns // 1000
        self.hist[b if b < len(self.hist) else len(self.hist) - 1] += 1
        if late_ns > self.max_ns:
            self.max_ns = late_ns
        self.count += 1

    def percentile_us(self, q: float) -> float:
        """Upper edge (us) of the bin holding the q-th percentile (0 with no samples)."""
        if self.count == 0:
            return 0.0
        c = np.cumsum(self.hist)
        k = int(np.searchsorted(c, q / 100.0 * self.count))
        return float(min(k + 1, len(self.hist)))

    @property
    def max_us(self) -> float:
        return self.max_ns / 1000.0


class RealtimePacer:
    """Absolute-deadline pacer: `wait()` until the release, `done()` after the work."""

    def __init__(self, period_s: float, spin_s: float = 200e-6, max_behind: int = 50,
                 clock: Callable[[], int] = time.perf_counter_ns) -> None:
        if period_s <= 0:
            raise ValueError("period must be > 0")
        self.period_ns = int(round(period_s * NS))
        self.spin_ns = int(max(0.0, min(spin_s, period_s)) * NS)
        self.max_behind = max_behind
        self.clock = clock
        self.release_ns = 0
        self.lateness = LatenessStats()
        self.work = LatenessStats()       # wall time of the work of one period
        self.periods = 0
        self.misses = 0
        self.skipped = 0
        self.last_missed = False

    def start(self, delay_s: float = 0.0) -> None:
        """First release `delay_s` from now."""
        self.release_ns = self.clock() + int(delay_s * NS)

    def reset_stats(self) -> None:
        self.lateness.reset()
        self.work.reset()
        self.periods = self.misses = self.skipped = 0

    def remaining_s(self) -> float:
        return (self.release_ns - self.clock()) / NS

    def wait(self, poll: Callable[[float], object] | None = None) -> int:
        """Block until the current release; returns the lateness (ns, >= 0).

        While more than the spin window is left, `poll(timeout_s)` is called (it should
        return no later than `timeout_s`); then the rest is spun."""
        release, spin = self.release_ns, self.spin_ns
        clock = self.clock
        while True:
            left = release - clock()
            if left <= spin:
                break
            if poll is not None:
                poll((left - spin) / NS)
            else:
                time.sleep((left - spin) / NS)
        while clock() < release:
            pass
        late = clock() - release
        self.lateness.add(late)
        return late

    def discipline(self, event_ns: int, offset_ns: int, gain: float = 0.25,
                   max_step_ns: int = 20_000) -> int:
        """Pull the release phase towards `event_ns + offset_ns` (modulo the period).

        A drive synchronises its control loop to the SYNC it receives; called at each
        SYNC arrival, this moves the next releases by at most `max_step_ns` per call
        (a slow phase lock: lateness is counted against the adjusted schedule, so the
        corrections do not show up as jitter). Returns the correction applied (ns)."""
        T = self.period_ns
        err = (self.release_ns - (event_ns + offset_ns) + T // 2) % T - T // 2
        step = int(max(-max_step_ns, min(max_step_ns, gain * err)))
        self.release_ns -= step
        return -step

    def done(self) -> bool:
        """Account the period that started at the current release and move to the next.

        Returns True when the period was a deadline miss. After a stall of more than
        `max_behind` periods the missed releases are dropped (counted in `skipped`)."""
        now = self.clock()
        start = self.release_ns
        self.work.add(now - start)
        nxt = start + self.period_ns
        missed = now > nxt
        self.periods += 1
        if missed:
            self.misses += 1
        self.last_missed = missed
        behind = (now - nxt) // self.period_ns
        if behind > self.max_behind:
            self.skipped += int(behind)
            nxt += int(behind) * self.period_ns
        self.release_ns = nxt
        return missed


def use_realtime_priority(priority: int) -> str:
    """Run this process (and the processes it starts from now on, which inherit the
    policy) under SCHED_FIFO at `priority` (1-99); 0 leaves the scheduling alone.

    Returns a one-line description of the scheduling in force; a refusal (no root, no
    CAP_SYS_NICE, no rtprio limit, no SCHED_FIFO on this OS) is described, not raised."""
    if priority == 0:
        return "normal scheduling"
    if not 1 <= priority <= 99:
        raise ValueError(f"real-time priority must be 1..99 (or 0 for none), got {priority}")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        return (f"normal scheduling (SCHED_FIFO {priority} refused: {why}; it needs root, "
                "CAP_SYS_NICE or an rtprio limit)")
    return f"SCHED_FIFO priority {priority}"


def use_normal_priority() -> None:
    """Back to the default time-sharing policy (SCHED_OTHER)."""
    try:
        if os.sched_getscheduler(0) != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (AttributeError, OSError):
        pass

