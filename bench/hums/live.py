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

from bench import BenchError
from bench.bus.logs import SIGNAL_COLUMNS
from bench.hums.indexes import Indexes, OnlineHums
from ema_contract.frames import FrameError, Frames
from ema_contract.states import NMTCommand
from plant_rt.params import PlantParams

TWO_PI = 2.0 * math.pi
ROW_COLUMNS = ("setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
               "current_a", "motor_speed_rad_s", "encoder_counts", "position_m")
LEVELS = ("HEALTHY", "DEGRADED", "WARNING", "FAILURE")


def level_of(ix: Indexes) -> int:
    """0..3 from the period's Ci against the thesis' threshold / warning / failure levels
    (0.93 / 0.80 / 0.56, section 6.3)."""
    from bench.hums.rul import FAILURE, THRESHOLD, WARNING
    ci = ix.ci_harmonic if math.isfinite(ix.ci_harmonic) else ix.ci
    if not math.isfinite(ci):
        return 0
    return 3 if ci < FAILURE else 2 if ci < WARNING else 1 if ci < THRESHOLD else 0


@dataclass
class PeriodResult:
    run: int
    period: int
    t_start_s: float
    indexes: Indexes
    level: int

    def row(self) -> dict[str, Any]:
        ix = self.indexes
        return {"run": self.run, "period": self.period, "t_start_s": self.t_start_s,
                "cp": ix.cp, "ci": ix.ci, "ci_harmonic": ix.ci_harmonic,
                "peak_ratio": ix.peak_ratio, "mean_error_m": ix.mean_error_m,
                "lost_motion_m": ix.lost_motion_m, "level": LEVELS[self.level]}


class LiveHums:
    """Frames in, per-period results out. Feed it with `feed(msg)`."""

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
        cob = self.frames.cob
        self._sync, self._nmt = cob["SYNC"], cob["NMT"]
        self._signals = {cob[n]: cols for n, cols in SIGNAL_COLUMNS.items()}
        self.run = 0
        self.frames_seen = 0
        self.bad_frames = 0
        self.last_sync: float | None = None        # monotonic time it was fed
        self.last_sync_stamp: float | None = None  # its bus timestamp
        self._online: OnlineHums | None = None
        self._row: dict[str, float] | None = None
        self._k = 0
        self._periods = 0

    def _new_run(self) -> None:
        self.run += 1
        self._online = OnlineHums(self.period_s, self.kp, self.mparams)
        self._row = None
        self._k = 0
        self._periods = 0

    def _flush_row(self) -> list[PeriodResult]:
        row, self._row = self._row, None
        if row is None or self._online is None:
            return []
        cols = {c: row.get(c, math.nan) for c in ROW_COLUMNS}
        counts = cols.pop("encoder_counts")
        cols["motor_angle_rad"] = counts * TWO_PI / self.cpr
        cols["t_s"] = self._k * self.dt
        self._k += 1
        out = []
        for ix in self._online.push(cols):
            out.append(PeriodResult(self.run, self._periods, self._periods * self.period_s,
                                    ix, level_of(ix)))
            self._periods += 1
        return out

    def feed(self, msg: can.Message) -> list[PeriodResult]:
        """One frame; returns the command periods it completed (usually none)."""
        self.frames_seen += 1
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return []
        cid = msg.arbitration_id
        if cid == self._sync:
            self.last_sync = time.monotonic()
            self.last_sync_stamp = msg.timestamp
            if self._online is None:      # joined mid-run: start here
                self._new_run()
            out = self._flush_row()
            self._row = {}
            return out
        if cid == self._nmt:
            try:
                _, sig = self.frames.decode(msg)  # type: ignore[misc]
            except (FrameError, TypeError):
                self.bad_frames += 1
                return []
            if sig["NMT_NodeId"] not in (0, self.frames.node_id):
                return []
            out = self._flush_row()     # the run's last row is complete: no SYNC follows
            if sig["NMT_Command"] == NMTCommand.START:
                self._new_run()
            return out
        cols = self._signals.get(cid)
        if cols is None or self._row is None:
            return []
        try:
            decoded = self.frames.decode(msg)
        except FrameError:
            self.bad_frames += 1
            return []
        if decoded is None:
            return []
        sig = decoded[1]
        for s, col in cols:
            self._row[col] = float(sig[s])
        return []

    def finish(self) -> list[PeriodResult]:
        """End of listening: the pending row (its frames have all arrived) is counted."""
        return self._flush_row()

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
    ci = ix.ci_harmonic if math.isfinite(ix.ci_harmonic) else ix.ci
    lm = ix.lost_motion_m * 1e6 if math.isfinite(ix.lost_motion_m) else float("nan")
    return (f"run {r.run} period {r.period:4d} t {r.t_start_s:8.2f} s  Cp {ix.cp:6.3f}  "
            f"Ci {ci:6.3f}  peak ratio {ix.peak_ratio:5.2f}  lost motion {lm:6.1f} um  "
            f"{LEVELS[r.level]}")
