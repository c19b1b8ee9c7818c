"""Lost samples of a trace: bridged when short, else the indexes that read them are
marked unavailable."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.hums.comparison import Indexes
from bench.hums.formulas import CURRENT_SIGNALS, LOST_MOTION_SIGNALS, POSITION_SIGNALS
from bench.signals.trace import Trace

BRIDGE_MAX_SAMPLES = 5
"""Longest run of missing samples (lost SYNCs, missing frames, NaN rows) that is bridged
by interpolation: 5 ms at 1 kHz, 1 % of the 2 Hz command period and 1/6 of the period of
the 15th harmonic (30 Hz), the highest line an index reads; over such a run a linear
bridge of a sine at 30 Hz is off by at most 15 % of that line's (small) amplitude, on
5 samples of the thousands an index integrates."""
BRIDGE_MAX_FRACTION = 0.02
"""Largest share of a signal's samples that may be bridged in all (as `bench gap`)."""

INDEX_SIGNALS: dict[str, tuple[str, ...]] = {
    "mean_error_m": POSITION_SIGNALS, "cp": POSITION_SIGNALS,
    "ci": CURRENT_SIGNALS, "ci_harmonic": CURRENT_SIGNALS, "peak_ratio": CURRENT_SIGNALS,
    "current_rms_a": CURRENT_SIGNALS, "harmonics_a": CURRENT_SIGNALS,
    "friction_current_a": CURRENT_SIGNALS + ("motor_speed_rad_s",),
    "lost_motion_m": LOST_MOTION_SIGNALS, "dead_time_s": LOST_MOTION_SIGNALS,
}
"""The measured signals each index of `Indexes` reads."""
HOLD_SIGNALS = ("mode", "status_word", "run")
"""Signals bridged by holding the previous value (states, not samples of a motion)."""


def missing_runs(y: np.ndarray) -> list[tuple[int, int]]:
    """(first index, length) of each run of non-finite samples of `y`."""
    bad = ~np.isfinite(np.asarray(y, dtype=float))
    if not bad.any():
        return []
    edges = np.diff(np.concatenate(([0], bad.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b - a)) for a, b in zip(starts, ends, strict=True)]


@dataclass
class Gaps:
    """The missing samples of one signal of a trace."""
    column: str
    n: int                           # samples in the trace
    runs: list[tuple[int, int]]      # (first index, length)

    @property
    def missing(self) -> int:
        return sum(k for _, k in self.runs)

    @property
    def longest(self) -> tuple[int, int]:
        return max(self.runs, key=lambda r: r[1])

    @property
    def bridgeable(self) -> bool:
        return (self.longest[1] <= BRIDGE_MAX_SAMPLES
                and self.missing <= BRIDGE_MAX_FRACTION * self.n)

    def describe(self, t: np.ndarray) -> str:
        at, k = self.longest
        return (f"{self.missing} samples missing in {self.column} (longest gap {k} samples "
                f"at t = {float(t[at]):.3f} s; up to {BRIDGE_MAX_SAMPLES} in a row and "
                f"{100 * BRIDGE_MAX_FRACTION:g} % in all can be bridged)")


def signal_gaps(trace: Trace, columns: tuple[str, ...]) -> dict[str, Gaps]:
    """The signals among `columns` with missing samples (a signal missing throughout is
    absent, not a gap)."""
    out = {}
    for c in columns:
        if c in trace and np.isfinite(trace[c]).any():
            runs = missing_runs(trace[c])
            if runs:
                out[c] = Gaps(c, len(trace), runs)
    return out


def bridge(trace: Trace, gaps: dict[str, Gaps]) -> Trace:
    """A copy of `trace` with the missing samples of the signals in `gaps` filled: linear
    interpolation in time (HOLD_SIGNALS: the previous value), the nearest value at the
    ends. Long gaps are filled too, so that no NaN reaches a filter or a spectrum; the
    caller marks what they make unavailable (`mark_unavailable`)."""
    cols = dict(trace.columns)
    t = trace.t
    for c in gaps:
        y = np.asarray(cols[c], dtype=float)
        ok = np.isfinite(y)
        if c in HOLD_SIGNALS:
            idx = np.maximum.accumulate(np.where(ok, np.arange(len(y)), -1))
            first = int(np.argmax(ok))
            y = y[np.where(idx < 0, first, idx)]
        else:
            y = np.interp(t, t[ok], y[ok])
        cols[c] = y
    return Trace(cols, dict(trace.meta))


def mark_unavailable(ix: Indexes, blocked: dict[str, str],
                     drive: tuple[str, ...] = ()) -> None:
    """Set to NaN (and explain in ``ix.unavailable``) every index that reads a signal in
    `blocked` (signal -> why); a blocked `drive` signal (the set-points of the monitoring
    model) makes every index unavailable."""
    why_all = next((blocked[c] for c in drive if c in blocked), None)
    for name, needs in INDEX_SIGNALS.items():
        why = why_all or next((blocked[c] for c in needs if c in blocked), None)
        if why is None:
            continue
        ix.unavailable[name] = f"not available: {why}"
        if name == "harmonics_a":
            ix.harmonics_a = []
        else:
            setattr(ix, name, math.nan)
    if why_all is not None:
        for name in ("nominal_current_rms_a", "nominal_lost_motion_m",
                     "nominal_friction_current_a"):
            setattr(ix, name, math.nan)
        ix.nominal_harmonics_a = []
