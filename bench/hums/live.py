"""The HUMS as a passive bus client: per-command-period indexes of a live run.

A HUMS box on an aircraft listens to the actuator's bus; it does not take part in the
control loop. `LiveHums` does the same: it reads every frame (the ECU's set-point frame,
which the ECU publishes for loggers and for this, RPDO1 and TPDO1-3, decoded through the
DBC), builds one row per SYNC period and hands the rows to `OnlineHums`, which returns
the `Indexes` of each completed command period against the monitoring model (the same
code as `period_indexes` on a log, so a live run and its replayed log give the same
numbers). A new run (NMT start) restarts the monitoring model.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import can
import numpy as np

from bench import BenchError
from bench.bus.rows import RowAssembler
from bench.core.verdict import Level, Verdict
from bench.hums import indexes as I
from bench.hums import verdict as V
from bench.hums.indexes import Indexes, OnlineHums
from ema_contract.frames import Frames, load_od
from plant_rt.params import PlantParams

TWO_PI = 2.0 * math.pi
ROW_COLUMNS = ("setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
               "current_a", "motor_speed_rad_s", "encoder_counts", "position_m")
BRIDGED = ("setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
           "current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m")
"""The columns pushed whose short gaps are bridged as the report bridges them."""


@dataclass
class PeriodResult:
    run: int
    period: int
    t_start_s: float
    indexes: Indexes
    verdict: Verdict
    """The report's verdict of this command period (`bench.hums.verdict.judge`)."""

    @property
    def level(self) -> Level:
        return self.verdict.level

    def row(self) -> dict[str, Any]:
        ix = self.indexes
        return {"run": self.run, "period": self.period, "t_start_s": self.t_start_s,
                "cp": ix.cp, "ci": V.judged_ci(ix.ci, ix.ci_harmonic),
                "ci_broadband": ix.ci, "ci_harmonic": ix.ci_harmonic,
                "peak_ratio": ix.peak_ratio, "mean_error_m": ix.mean_error_m,
                "lost_motion_m": ix.lost_motion_m, "level": self.level.name}


class _RowQueue:
    """Row sink of the `RowAssembler`: the rows it writes, queued as (run, {column:
    value}) until `LiveHums` takes them."""

    def __init__(self) -> None:
        self.n = 0
        self.out: list[tuple[int, dict[str, float]]] = []

    def __len__(self) -> int:
        return self.n

    def add(self, bus_time_s: float, run: int, group: Any) -> None:
        vals: dict[str, float] = {}
        if group is not None:
            for _, v in group.frames.values():
                vals.update(v)
        self.n += 1
        self.out.append((run, vals))


class _Bridge:
    """Short gaps of each column filled as `bench.hums.indexes.bridge` fills them on a
    whole log (linear in time; HOLD_SIGNALS: the previous value; a leading gap: the first
    value): rows are held while a gap is open and released when it closes. A gap longer
    than BRIDGE_MAX_SAMPLES is not waited for: its rows go on with the previous value
    held (the report would mark the indexes that read it 'not available'), counted in
    ``unbridged``."""

    def __init__(self) -> None:
        self.held: list[dict[str, float]] = []
        self.last: dict[str, tuple[float, float]] = {}      # column -> (t, value)
        self.unbridged = 0

    def push(self, row: dict[str, float]) -> list[dict[str, float]]:
        self.held.append(row)
        for c in BRIDGED:
            y = row[c]
            if not math.isfinite(y):
                continue
            gap = []
            for r in reversed(self.held[:-1]):
                if math.isfinite(r[c]):
                    break
                gap.append(r)
            if not gap:
                self.last[c] = (row["t_s"], y)
                continue
            gap.reverse()
            prev = self.last.get(c)
            for r in gap:
                if prev is None or c in I.HOLD_SIGNALS and prev is not None:
                    r[c] = y if prev is None else prev[1]
                else:
                    r[c] = float(np.interp(r["t_s"], [prev[0], row["t_s"]], [prev[1], y]))
            self.last[c] = (row["t_s"], y)
        return self._release(False)

    def _release(self, flush: bool) -> list[dict[str, float]]:
        out = []
        while self.held:
            r = self.held[0]
            open_ = [c for c in BRIDGED if not math.isfinite(r[c]) and c in self.last
                     or not math.isfinite(r[c]) and c not in self.last and not flush]
            if open_ and not flush and len(self.held) <= I.BRIDGE_MAX_SAMPLES:
                break
            for c in BRIDGED:
                if not math.isfinite(r[c]) and c in self.last:
                    r[c] = self.last[c][1]
                    self.unbridged += 1
            out.append(self.held.pop(0))
        return out

    def finish(self) -> list[dict[str, float]]:
        return self._release(True)


class LiveHums:
    """Frames in, per-period results out. Feed it with `feed(msg)`.

    The rows are those of the log decoder (`bench.bus.rows.RowAssembler`: lost SYNCs,
    duplicates, late and missing frames handled and counted alike, ``count``), their
    short gaps bridged as the report bridges them, and each period judged by the
    report's verdict (`bench.hums.verdict.judge`). Not done live: sorting a log whose
    lines are out of time order (that needs the whole log), and the report's 2 % limit
    on bridged samples (it needs the whole signal)."""

    def __init__(self, period_s: float, params: PlantParams | None = None,
                 node_id: int | None = None, position_kp_rad_s_per_m: float | None = None
                 ) -> None:
        from bench.hums import monitor as M
        self.params = params or PlantParams()
        self.frames = Frames(node_id)
        self.period_s = float(period_s)
        if position_kp_rad_s_per_m is None:
            position_kp_rad_s_per_m = M.fitted(self.params)[0].gain_rad_s_per_m
        self.kp = position_kp_rad_s_per_m
        self.mparams = M.MonitorParams.from_plant(self.params)
        self.dt = self.params.sim.sync_period_s
        self.cpr = float(self.params.sensors.encoder_counts_per_rev)
        self._sync, self._nmt = self.frames.cob["SYNC"], self.frames.cob["NMT"]
        self._queue = _RowQueue()
        self._od = load_od(self.frames.node_id)
        self.assembler = RowAssembler(self.frames, int(self._od[0x1019].default), self._queue)
        self.run = 0
        self.last_sync: float | None = None        # monotonic time it was fed
        self.last_sync_stamp: float | None = None  # its bus timestamp
        self._online: OnlineHums | None = None
        self._bridge = _Bridge()
        self._row_run: int | None = None
        self._modes: list[float] = []
        self._k = 0
        self._periods = 0
        from bench.usage.online import OnlineUsage
        self.usage = OnlineUsage(self._run_params, self._serial)
        """The usage of each run (bench/usage), from the same rows, gaps unbridged."""

    def _run_params(self) -> PlantParams:
        """The run's parameters as the log decoder takes them: those the ECU's SDO traffic
        revealed when it revealed them all, else the nominal ones."""
        from bench.bus.sdo import sdo_values
        from plant_rt.paramobjects import ParamObjects
        od = self._od
        pobj = ParamObjects(od)
        values = sdo_values(self.assembler.sdo, pobj, od)
        if len(values) >= len(pobj.by_name):
            try:
                return PlantParams().with_dict(values)
            except ValueError:
                pass
        return self.params

    def _serial(self) -> str:
        """The serial number the ECU read (0x1018 sub 4), else unknown."""
        from bench.bus.sdo import serial_of
        return serial_of(self.assembler.sdo, self._od)

    @property
    def count(self) -> dict[str, int]:
        """The damage counted by the row assembler (as ``trace.meta`` of a log)."""
        return self.assembler.count

    @property
    def frames_seen(self) -> int:
        return self.assembler.count["frames"]

    @property
    def bad_frames(self) -> int:
        return self.assembler.count["bad_frames"]

    def _new_run(self) -> list[PeriodResult]:
        out = self._push(self._bridge.finish())
        self.run += 1
        self._online = OnlineHums(self.period_s, self.kp, self.mparams)
        self._bridge = _Bridge()
        self._modes = []
        self._k = 0
        self._periods = 0
        return out

    def _take_rows(self) -> list[PeriodResult]:
        out: list[PeriodResult] = []
        rows, self._queue.out = self._queue.out, []
        for run, vals in rows:
            self.usage.push(run, vals)
            if run != self._row_run or self._online is None:   # a new run (or joined one)
                out += self._new_run()
                self._row_run = run
            cols = {c: vals.get(c, math.nan) for c in ROW_COLUMNS}
            cols["motor_angle_rad"] = cols.pop("encoder_counts") * TWO_PI / self.cpr
            cols["t_s"] = self._k * self.dt
            self._k += 1
            out += self._push(self._bridge.push(cols))
        return out

    def _push(self, rows: list[dict[str, float]]) -> list[PeriodResult]:
        out = []
        for cols in rows:
            assert self._online is not None
            self._modes.append(cols["mode"])
            try:
                done = self._online.push(cols)
            except BenchError as exc:     # a signal missing through the whole period
                t0 = self._periods * self.period_s
                done = [Indexes(t0, t0 + self.period_s,
                                unavailable={k: f"not available: {exc}"
                                             for k in I.INDEX_SIGNALS})]
            for ix in done:
                m = np.array(self._modes[:self._online.m])
                del self._modes[:self._online.m]
                m = m[np.isfinite(m)]
                mode = int(np.bincount(m.astype(int)).argmax()) if len(m) else 0
                out.append(PeriodResult(self.run, self._periods,
                                        self._periods * self.period_s, ix, V.judge(ix, mode)))
                self._periods += 1
        return out

    def feed(self, msg: can.Message) -> list[PeriodResult]:
        """One frame; returns the command periods it completed (usually none)."""
        if (msg.arbitration_id == self._sync and not msg.is_extended_id
                and not msg.is_error_frame and not msg.is_remote_frame):
            self.last_sync = time.monotonic()
            self.last_sync_stamp = msg.timestamp
        self.assembler.feed(msg)
        if (msg.arbitration_id == self._nmt and not msg.is_extended_id and len(msg.data) == 2
                and msg.data[1] in (0, self.frames.node_id)):
            self.assembler.close_period()   # the run's last row is complete: no SYNC follows
        return self._take_rows() if self._queue.out else []

    def finish(self) -> list[PeriodResult]:
        """End of listening: the pending row (its frames have all arrived) is counted."""
        self.assembler.finish()
        out = self._take_rows()
        return out + self._push(self._bridge.finish())

    def feed_all(self, msgs: Iterable[can.Message]) -> list[PeriodResult]:
        out: list[PeriodResult] = []
        for m in msgs:
            out.extend(self.feed(m))
        return out


def watch(bus: can.BusABC, hums: LiveHums, on_result: Callable[[PeriodResult], None],
          duration_s: float | None = None, idle_s: float = 2.0,
          ready: Callable[[], None] | None = None) -> int:
    """Listen until `duration_s` has passed, or no SYNC for `idle_s` after a run was seen
    (the run ended); returns the number of command periods reported."""
    n = 0
    t_end = None if duration_s is None else time.monotonic() + duration_s
    if ready is not None:
        ready()
    # "no SYNC for idle_s" is judged on the bus's clock (frame timestamps) while frames
    # come, and on the wall clock only when the bus is quiet: the watcher's own work (the
    # first command period loads the compiled monitor) must not count as idle time
    while True:
        if t_end is not None and time.monotonic() >= t_end:
            break
        try:
            msg = bus.recv(timeout=0.1)
        except (can.CanError, OSError) as exc:
            raise BenchError(f"the bus connection failed: {exc}") from None
        if msg is None:
            if hums.last_sync is not None and time.monotonic() - hums.last_sync > idle_s:
                break
            continue
        if hums.last_sync_stamp is not None and msg.timestamp - hums.last_sync_stamp > idle_s:
            break
        for r in hums.feed(msg):
            on_result(r)
            n += 1
    for r in hums.finish():
        on_result(r)
        n += 1
    return n


def format_result(r: PeriodResult) -> str:
    ix = r.indexes
    ci = V.judged_ci(ix.ci, ix.ci_harmonic)
    lm = ix.lost_motion_m * 1e6 if math.isfinite(ix.lost_motion_m) else float("nan")
    return (f"run {r.run} period {r.period:4d} t {r.t_start_s:8.2f} s  Cp {ix.cp:6.3f}  "
            f"Ci {ci:6.3f}  peak ratio {ix.peak_ratio:5.2f}  lost motion {lm:6.1f} um  "
            f"{r.level.name}")
