"""The usage of the runs a passive listener sees (`bench hums watch`): the rows of the
row assembler (`bench.bus.rows`, the same rows `bench usage` gets from the run's log, gaps
unbridged) go into one `UsageAccumulator` per run, in blocks, so that the totals at the
end of a run equal `bench usage` on its log.

The run's parameters (SYNC period, encoder resolution, lead, reducer ratio, C_a, preload) are those the ECU's SDO traffic
revealed when it revealed them all (as the log decoder takes them), else the watcher's
nominal ones; the serial number is the one the ECU read from 0x1018 sub 4. The hystereses
are the settings': the noise rule of `bench usage` (`bench.usage.hysteresis`) needs the
whole log's noise before the first row is counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bench.usage.accumulator import Geometry, UsageAccumulator
from bench.usage.hysteresis import of_settings
from bench.usage.settings import UsageSettings
from bench.usage.summary import UNKNOWN, UsageSummary, accumulate
from plant_rt.params import PlantParams

COLUMNS = ("encoder_counts", "position_m", "load_force_n", "current_a", "motor_speed_rad_s",
           "winding_temperature_k")
TWO_PI = 2.0 * math.pi
BLOCK = 256
"""Rows pushed at a time (the totals do not depend on it)."""
LIVE = "live: no noise rule, it needs the whole log's noise"
"""Why the hystereses are the settings' (`bench.usage.hysteresis`): on a log of the bench's
own plant `bench usage` keeps the settings too, so the totals agree."""


class OnlineUsage:
    """Rows in per run (`push`), usage out (`current`, `runs`, `totals`)."""

    def __init__(self, params: Callable[[], PlantParams], serial: Callable[[], str],
                 settings: UsageSettings | None = None) -> None:
        self._params, self._serial = params, serial
        self.settings = settings or UsageSettings()
        self.done: list[UsageSummary] = []
        self._run: int | None = None
        self._acc: UsageAccumulator | None = None
        self._cpr = 1.0
        self._rows: list[tuple[float, ...]] = []

    def push(self, run: int, vals: dict[str, float]) -> None:
        """One row of run `run` (columns of `bench.bus.rows`; absent ones are NaN)."""
        if run != self._run or self._acc is None:
            self.end_run()
            p = self._params()
            self._acc = UsageAccumulator(p.sim.sync_period_s, Geometry.of(p, self.settings),
                                         self.settings, of_settings(self.settings, LIVE))
            self._cpr = float(p.sensors.encoder_counts_per_rev)
            self._run = run
        self._rows.append(tuple(vals.get(c, math.nan) for c in COLUMNS))
        if len(self._rows) >= BLOCK:
            self._flush()

    def _flush(self) -> None:
        if not self._rows or self._acc is None:
            return
        a = np.array(self._rows, dtype=float).reshape(len(self._rows), len(COLUMNS))
        self._rows = []
        cols = {c: a[:, k] for k, c in enumerate(COLUMNS)}
        # as the log decoder computes it (bench.bus.logs), to the last bit
        cols["motor_angle_rad"] = cols.pop("encoder_counts") * TWO_PI / self._cpr
        self._acc.push(cols)

    def current(self) -> UsageSummary | None:
        """The usage of the run going on (None before the first row)."""
        if self._acc is None:
            return None
        self._flush()
        return self._acc.summary(self._serial(), f"live run {self._run}")

    def end_run(self) -> UsageSummary | None:
        """Close the run going on; its usage (None if there was none)."""
        s = self.current()
        if s is not None:
            self.done.append(s)
        self._acc, self._run = None, None
        return s

    def runs(self) -> list[UsageSummary]:
        """Every run so far, the one going on last."""
        cur = self.current()
        return self.done + ([cur] if cur is not None else [])

    def totals(self) -> dict[str, UsageSummary]:
        """Accumulated per actuator (serial)."""
        return accumulate(self.runs())


__all__ = ["UNKNOWN", "OnlineUsage"]
