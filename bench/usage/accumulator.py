"""The usage of a run, computed as the rows come: `UsageAccumulator.push` takes a block
of rows (a whole trace, or one row of the live watcher) and `summary` says the usage so
far. Blocks of any size give the same numbers (the hysteresis trackers are resumable,
everything else is a sum), so a live run and its log agree (`tests/unit/test_usage.py`).

`usage_of_trace` is the whole-trace entry point: the position hysteresis is raised to ten
times the log's own position noise where that is larger (`bench.usage.hysteresis`); the
geometry (lead, reducer ratio), the rating C_a and the preload come from the trace's plant
parameters when it carries them (an in-process run, a bus run, a log whose SDO traffic had
them all), else from the defaults of `plant_rt.params`; the serial from the log's SDO
traffic (object 0x1018 sub 4) or from what the ECU read (``meta["node"]["identity"]``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import rainflow

from bench import BenchError
from bench.signals.estimators import motion_regimes
from bench.signals.trace import Trace
from bench.usage import hysteresis as H
from bench.usage import life
from bench.usage.settings import (
    LOAD_EDGES_N,
    LOAD_MEAN_EDGES_N,
    LOAD_RANGE_EDGES_N,
    POS_MEAN_EDGES_M,
    POS_RANGE_EDGES_M,
    TEMP_EDGES_K,
    UsageSettings,
)
from bench.usage.summary import UNKNOWN, UsageSummary, blank
from bench.usage.tracker import Tracker
from plant_rt.params import ParameterError, PlantParams

TWO_PI = 2.0 * math.pi
TEMPERATURE_COLUMNS = ("winding_temperature_k", "temperature_k")
"""The winding temperature: from the bus (TPDO3), else the simulation's truth column."""


@dataclass(frozen=True)
class Geometry:
    """What turns motor angle into screw revolutions and load into life."""
    lead_m: float
    ratio: float                 # screw speed / motor speed
    load_rating_n: float         # C_a
    preload_n: float

    @classmethod
    def of(cls, params: PlantParams, settings: UsageSettings) -> Geometry:
        pre = settings.preload_n if settings.preload_n >= 0 else params.effects.preload_n
        return cls(params.screw.lead_m, params.reducer.ratio,
                   params.screw.dynamic_load_rating_n, float(pre))


class UsageAccumulator:
    """Rows in (`push`), usage out (`summary`); see the module docstring."""

    def __init__(self, period_s: float, geometry: Geometry,
                 settings: UsageSettings | None = None,
                 hysteresis: Mapping[str, H.Hysteresis] | None = None) -> None:
        """`hysteresis`: each counter's (`bench.usage.hysteresis.of_log`); default the
        settings' alone."""
        if not (math.isfinite(period_s) and period_s > 0):
            raise BenchError(f"usage: the sample period must be > 0 s, not {period_s}")
        self.dt = float(period_s)
        self.geo = geometry
        self.settings = settings or UsageSettings()
        s = self.settings
        if not s.dwell_speed_m_s <= s.fast_speed_m_s:
            raise BenchError(f"usage: dwell_speed_m_s {s.dwell_speed_m_s:g} is above "
                             f"fast_speed_m_s {s.fast_speed_m_s:g}: a dwell slower than fast")
        h = dict(hysteresis or H.of_settings(s))
        self.screw = Tracker(h["reversal"].used / geometry.lead_m)   # in revolutions
        self.position = Tracker(h["position"].used)
        self.load = Tracker(h["load"].used)
        self.s = UsageSummary(load_rating_n=geometry.load_rating_n,
                              preload_mode=s.preload_mode, preload_n=geometry.preload_n)
        self._record(h)
        self._last_load = math.nan
        self._seen = dict.fromkeys(NEEDS, 0)

    def _record(self, h: Mapping[str, H.Hysteresis]) -> None:
        """The hystereses used and why (the why names the log's noise)."""
        s = self.s
        s.position_hysteresis_m, s.load_hysteresis_n = h["position"].used, h["load"].used
        s.hysteresis = {c: x.why() for c, x in h.items()}

    def push(self, cols: Mapping[str, Any]) -> None:
        """A block of rows: columns by trace name (``motor_angle_rad``, ``position_m``,
        ``load_force_n``, ``current_a``, ``motor_speed_rad_s``, the winding temperature);
        a missing column is NaN throughout."""
        n = len(next(iter(cols.values()))) if cols else 0
        if n == 0:
            return
        nan = np.full(n, math.nan)

        def col(name: str) -> np.ndarray:
            return np.asarray(cols[name], dtype=float) if name in cols else nan

        s, dt = self.s, self.dt
        for c in self._seen:
            names = TEMPERATURE_COLUMNS if c == TEMPERATURE_COLUMNS[0] else (c,)
            self._seen[c] += sum(int(np.isfinite(col(x)).sum()) for x in names if x in cols)
        s.samples += n
        s.duration_s += n * dt
        drev = self.screw.push(col("motor_angle_rad") * (self.geo.ratio / TWO_PI))
        adrev = np.abs(drev)
        s.screw_revolutions += float(adrev.sum())
        s.nut_travel_m = s.screw_revolutions * self.geo.lead_m
        self.position.push(col("position_m"))
        raw_load = col("load_force_n")
        self.load.push(raw_load)
        load = self._held(raw_load)
        self._life(adrev, load, raw_load)
        cur = col("current_a")
        s.i2t_a2s += float(np.nansum(cur * cur)) * dt
        temp = next((col(c) for c in TEMPERATURE_COLUMNS if c in cols), nan)
        fin = np.isfinite(temp)
        if fin.any():
            s.temperature_max_k = max(s.temperature_max_k, float(temp[fin].max()))
            s.temperature_time_s += np.histogram(temp[fin], TEMP_EDGES_K)[0] * dt
        self._regimes(col("motor_speed_rad_s"), adrev)

    def _held(self, raw: np.ndarray) -> np.ndarray:
        """The load with NaN samples holding the last reading (0 before the first)."""
        fin = np.isfinite(raw)
        idx = np.where(fin, np.arange(len(raw)), -1)
        np.maximum.accumulate(idx, out=idx)
        first = 0.0 if math.isnan(self._last_load) else self._last_load
        out = np.where(idx >= 0, raw[np.maximum(idx, 0)], first)
        if fin.any():
            self._last_load = float(raw[fin][-1])
        return out

    def _life(self, adrev: np.ndarray, load: np.ndarray, raw: np.ndarray) -> None:
        s, ca = self.s, self.geo.load_rating_n
        fin = np.isfinite(raw)
        s.load_samples += int(fin.sum())
        if fin.any():
            s.load_max_n = max(s.load_max_n, float(raw[fin].max()))
            s.load_min_n = min(s.load_min_n, float(raw[fin].min()))
        s.load_cube_sum += float(np.sum(adrev * np.abs(load) ** 3))
        s.damage += life.damage(adrev, load, ca)
        f1, f2 = life.nut_loads(load, self.geo.preload_n)
        s.damage_nut1 += life.damage(adrev, f1, ca)
        s.damage_nut2 += life.damage(adrev, f2, ca)
        s.load_spectrum_rev += np.histogram(load, LOAD_EDGES_N, weights=adrev)[0]

    def _regimes(self, motor_speed: np.ndarray, adrev: np.ndarray) -> None:
        s, st = self.s, self.settings
        v = np.abs(motor_speed) * (self.geo.ratio * self.geo.lead_m / TWO_PI)
        # a speed at an edge is in the regime above it: dwell below dwell_speed_m_s
        reg = motion_regimes(v, (st.dwell_speed_m_s, st.fast_speed_m_s), at_edge="upper")
        dwell, slow, fast = reg == 0, reg == 1, reg == 2
        s.time_unknown_regime_s += float((reg < 0).sum()) * self.dt
        for name, m in (("dwell", dwell), ("slow", slow), ("fast", fast)):
            setattr(s, f"{name}_s", getattr(s, f"{name}_s") + float(m.sum()) * self.dt)
            setattr(s, f"revolutions_{name}",
                    getattr(s, f"revolutions_{name}") + float(adrev[m].sum()))

    def summary(self, serial: str = UNKNOWN, source: str = "") -> UsageSummary:
        """The usage so far (a copy; pushing on goes on from where it was)."""
        s = replace(self.s, actuator_serial=serial, source=source,
                    load_spectrum_rev=self.s.load_spectrum_rev.copy(),
                    temperature_time_s=self.s.temperature_time_s.copy())
        s.reversals = float(self.screw.reversals)
        s.position_cycles, s.position_range_max_m, s.position_rainflow = _rainflow(
            self.position.series(), POS_RANGE_EDGES_M, POS_MEAN_EDGES_M)
        s.load_cycles, s.load_range_max_n, s.load_rainflow = _rainflow(
            self.load.series(), LOAD_RANGE_EDGES_N, LOAD_MEAN_EDGES_N)
        self._unavailable(s)
        return s

    def _unavailable(self, s: UsageSummary) -> None:
        """What the signals seen cannot give: NaN (null in JSON, "n/a" in the table) with
        the reason in `s.not_available`, not 0."""
        lack: dict[str, list[str]] = {}
        for sig, names in NEEDS.items():
            if not self._seen[sig]:
                for q in names:
                    lack.setdefault(q, []).append(sig)
        na = {q: f"needs {' and '.join(sigs)}" for q, sigs in lack.items()}
        blank(s, na)
        s.not_available = na


def _rainflow(points: np.ndarray, range_edges: np.ndarray, mean_edges: np.ndarray
              ) -> tuple[float, float, np.ndarray]:
    """Rainflow count (ASTM E1049, `rainflow.extract_cycles`) of a turning-point series:
    cycles (half cycles count 0.5), largest range, range x mean matrix."""
    shape = (len(range_edges) - 1, len(mean_edges) - 1)
    if len(points) < 2:
        return 0.0, 0.0, np.zeros(shape)
    cyc = np.array([(r, m, c) for r, m, c, _, _ in rainflow.extract_cycles(points)])
    if not len(cyc):
        return 0.0, 0.0, np.zeros(shape)
    mat = np.histogram2d(cyc[:, 0], cyc[:, 1], [range_edges, mean_edges],
                         weights=cyc[:, 2])[0]
    return float(cyc[:, 2].sum()), float(cyc[:, 0].max()), mat


NEEDS: dict[str, tuple[str, ...]] = {
    "motor_angle_rad": ("screw_revolutions", "nut_travel_m", "reversals",
                        "revolutions_dwell", "revolutions_slow",
                        "revolutions_fast", "load_cube_sum", "damage", "damage_nut1",
                        "damage_nut2", "load_spectrum_rev", "fm_n", "l10_rev",
                        "life_consumed"),
    "load_force_n": ("load_cycles", "load_range_max_n", "load_rainflow", "load_cube_sum",
                     "damage", "damage_nut1", "damage_nut2", "load_spectrum_rev", "fm_n",
                     "l10_rev", "life_consumed"),
    "position_m": ("position_cycles", "position_range_max_m", "position_rainflow"),
    "current_a": ("i2t_a2s", "current_rms_a"),
    "motor_speed_rad_s": ("dwell_s", "slow_s", "fast_s", "revolutions_dwell",
                          "revolutions_slow", "revolutions_fast"),
    TEMPERATURE_COLUMNS[0]: ("temperature_max_k", "temperature_time_s"),
}
"""The quantities each signal is needed for (`UsageAccumulator._unavailable`). The nut
travel and the reversals are not taken from the position when there is no motor angle:
through the position hysteresis (chosen for the thesis' LVDT) a noisier position sensor's
noise would count as motion (a 25 Hz rig's table: 57 reversals on one out-and-back)."""


def trace_params(trace: Trace) -> PlantParams:
    """The plant parameters a trace carries (``meta["params"]``), else the defaults."""
    p = trace.meta.get("params")
    if isinstance(p, dict):
        try:
            return PlantParams.from_dict(p)
        except (ParameterError, TypeError, ValueError):
            pass
    return PlantParams()


def trace_serial(trace: Trace) -> str:
    """The actuator's serial number (0x1018 sub 4) as the trace knows it, else unknown."""
    serial = trace.meta.get("actuator_serial")
    if serial is None:
        node = trace.meta.get("node")
        if isinstance(node, dict):
            serial = (node.get("identity") or {}).get("serial")
    return UNKNOWN if serial is None or serial == UNKNOWN else str(serial)


def usage_of_trace(trace: Trace, settings: UsageSettings | None = None,
                   params: PlantParams | None = None, serial: str | None = None
                   ) -> UsageSummary:
    """The usage of one run (module docstring); `params` / `serial` override the trace's."""
    settings = settings or UsageSettings()
    params = params or trace_params(trace)
    period = trace.meta.get("period_s")
    if not isinstance(period, int | float) or not period > 0:
        period = trace.dt if len(trace) > 1 else params.sim.sync_period_s
    acc = UsageAccumulator(float(period), Geometry.of(params, settings), settings,
                           H.of_log(settings, trace.columns))
    acc.push(trace.columns)
    return acc.summary(serial or trace_serial(trace), str(trace.meta.get("source", "")))
