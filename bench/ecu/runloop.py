"""The ECU's control loop: one SYNC period after another, the trace of the run."""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import asdict
from typing import Any

from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench import BenchError
from bench.ecu.claim import EcuClaim
from bench.ecu.errors import (
    FAILING_BITS,
    FAILING_TEXT,
    REPORTING_EMCY,
    Interrupted,
    PlantFault,
    PlantLost,
    _at,
    status_names,
)
from bench.ecu.period import EcuStats, PeriodSteps
from bench.ecu.signals import StopSignal
from bench.profiles.catalog import Profile
from bench.signals.trace import Trace, max_rows
from bench.sim.control import MODE_IDLE, Controller, ControllerParams
from ema_contract.states import NMTCommand, Pace
from plant_rt.params import PlantParams


class RunLoop(EcuClaim):
    """Part of `Ecu`: `run` a profile on the prepared node."""

    def run(self, profile: Profile, params: PlantParams, cparams: ControllerParams | None = None,
            pace: Pace = Pace.SYNC, duration_s: float | None = None, progress: bool = False,
            spin_us: int = 200, on_period: Callable[[int], None] | None = None,
            stop: StopSignal | None = None, stamp: str = "bus") -> Trace:
        """Run `profile` on the prepared plant; returns the trace (partial on error: the
        error is raised after the trace is stored in `self.partial`, and the node is set
        PRE-OPERATIONAL). The run fails (`PlantFault`) as soon as the plant reports a
        condition that changes its behaviour (FAILING_BITS, any EMCY outside
        REPORTING_EMCY), another ECU shows up (`ForeignEcu`), the log cannot be written
        (`LogWriteError`) or `stop` records a signal (`Interrupted`). `stamp` "bus"
        stamps the log's frames in bus time in lockstep (`bench.ecu.busclock`), "wall"
        on the wall clock (always so in real time, where the bus runs on it)."""
        if stamp not in ("bus", "wall"):
            raise BenchError(f"stamp must be 'bus' or 'wall', not {stamp!r}")
        ts = params.sim.sync_period_s
        cparams = cparams or ControllerParams(sample_period_s=ts)
        if not math.isclose(cparams.sample_period_s, ts):
            raise BenchError(f"controller period {cparams.sample_period_s} s differs from the "
                             f"plant's SYNC period {ts} s")
        dur = profile.duration_s if duration_s is None else duration_s
        stats = EcuStats()
        steps = PeriodSteps(self, profile, params, cparams, pace,
                            run_periods(dur, ts), spin_us, stop, stats)
        steps.on_period = on_period
        steps.bus_stamps = stamp == "bus" and pace == Pace.SYNC
        self.partial = None
        self._stop = stop
        steps.setup(progress)
        self.unlisten()
        self.tap = steps.tap       # from here on every frame logged also makes the rows
        # keep full garbage collections (0.1 s with numba and scipy loaded) out of the
        # control loop: what exists now is not scanned again until the run ends. Frozen
        # without a collection first: a full one holds the interpreter lock 0.1-0.3 s,
        # which starves the set-up heartbeat thread while the node's consumer watches it
        # (its garbage is collected after the run, when `unfreeze` returns it)
        gc.freeze()
        if stop is not None:
            stop.defer = True
        error: BaseException | None = None
        try:
            self._start_run(steps)
            pacer = steps.pacer
            for k in range(steps.n):
                steps.sync(k)
                steps.collect(k)
                steps.check(k)
                if pacer is not None and len(steps.latest) < 3:
                    steps.wait_first(k)
                    continue
                steps.control(k)
                steps.end(k)
        except BaseException as exc:  # noqa: BLE001 - stored, re-raised below
            error = exc
        finally:
            if stop is not None:
                stop.defer = False
            gc.unfreeze()
            steps.close()
        if error is not None:
            trace = self.partial = self._trace(steps)
            trace.meta["error"] = str(error) or type(error).__name__
            if self.log is not None:
                stats.frames_logged = self.log.count
            trace.meta["ecu"] = asdict(stats)
            self.abort()
            raise error
        self.log_clock.period(steps.n)     # what follows the run follows its last period
        end = self._finish(stats)
        trace = self.partial = self._trace(steps)
        trace.meta.update(end)
        return trace

    def start_heartbeat(self) -> None:
        """The set-up heartbeat (`EcuLink.start_heartbeat`), once the controller's compiled
        step is loaded: the first heartbeat arms the node's consumer (0x1016), and loading
        the step holds the interpreter lock for about 0.1 s at a time (0.4 s in all, more
        on a loaded machine), long enough to starve the heartbeat thread."""
        Controller().step(0.0, 0.0, MODE_IDLE, 0.0, 0.0)
        super().start_heartbeat()

    def _trace(self, steps: PeriodSteps) -> Trace:
        """The run's trace from the rows of the frames recorded so far; the rows stop."""
        try:
            return steps.trace()
        finally:
            self.tap = None

    def _start_run(self, steps: PeriodSteps) -> None:
        """The last checks, the ECU's heartbeat, NMT START, the pacer's first release."""
        self.stop_heartbeat()
        self.check_foreign()
        self.check_receive()
        self._hb_next = 0.0
        self.heartbeat()
        self._started = True
        self.nmt(NMTCommand.START)
        steps.emcy_seen = self._emcy_seen = len(self.emcy)
        if steps.pacer is not None:
            steps.pacer.start(5 * steps.ts)
        if steps.bus_stamps:
            self.log_clock.start(steps.ts)

    def _status_fault(self, word: int, k: int, ts: float) -> PlantFault:
        """The error for a status word with a FAILING_BITS bit set at SYNC k."""
        label = next(lb for bit, lb in FAILING_BITS.items() if word & bit)
        return PlantFault(f"the plant reported {FAILING_TEXT[label]}{_at(k, ts)}: status "
                          f"word 0x{word:04X} ({', '.join(status_names(word))}); the run "
                          f"is not valid")

    def _check_emcy(self, seen: int, k: int, ts: float) -> int:
        """PlantFault for the first EMCY since index `seen` outside REPORTING_EMCY;
        returns the new count of EMCYs checked."""
        for e in self.emcy[seen:]:
            name = e["name"]
            if name == "heartbeat_lost" and e["cycle"] == 0:
                continue    # latched before the plant's first period: cleared at SYNC 1
            if name not in REPORTING_EMCY:
                what = FAILING_TEXT.get(name, f"an emergency {name} unknown to the bench")
                raise PlantFault(f"the plant reported {what}{_at(k, ts)}: EMCY "
                                 f"0x{e['code']:04X} {name} (plant cycle {e['cycle']}); the "
                                 f"run is not valid")
        return len(self.emcy)

    def _finish(self, stats: EcuStats) -> dict[str, Any]:
        """Orderly end: drive to PRE-OPERATIONAL, stop heartbeat monitoring, counters;
        returns the trace's metadata from it."""
        meta: dict[str, Any] = {}
        self.listen()
        try:
            self.nmt(NMTCommand.ENTER_PRE_OPERATIONAL)
            self.sdo_write((0x1016, 1), 0)     # orderly log-out: stop consuming our heartbeat
            meta["plant_counters"] = self.read_status()
        except (BenchError, SdoAbortedError, SdoCommunicationError) as exc:
            meta["plant_counters"] = {"error": str(exc)}
        time.sleep(0.02)   # let the last answers reach the log (and the rows)
        meta["emcy"] = list(self.emcy)
        if self.log is not None:
            stats.frames_logged = self.log.count
        meta["ecu"] = asdict(stats)
        return meta

    def _send_sync(self) -> None:
        self._sync_counter = self._sync_counter % self._sync_max + 1
        self.send(self.frames.encode("SYNC", {"SYNC_Counter": self._sync_counter}))

    def _check_alive(self, k: int, ts: float) -> None:
        age = None if self.plant_hb is None else self._clock() - self.plant_hb
        timeout = 3 * self.frames.cycle_time_ms("EMA_Heartbeat") / 1000.0 + 0.05
        if age is None or age > timeout:
            seen = "never" if age is None else f"{age:.2f} s ago"
            raise PlantLost(f"the plant stopped answering at t = {k * ts:.3f} s (SYNC {k}): "
                            f"no TPDO, last heartbeat {seen}")

    def _wait_tpdos(self, poll, fresh: set[str], k: int, ts: float) -> None:
        """Lockstep: wait for TPDO1-3 of this SYNC (the plant answers every SYNC), with the
        heartbeat on the wall clock; a signal or a failed log ends a long wait."""
        start = self._clock()
        stop, log = self._stop, self.log
        while len(fresh) < 3:
            poll(0.1)
            self.heartbeat()
            waited = self._clock() - start
            if len(fresh) < 3 and waited > 0.05:
                if stop is not None and stop.signum is not None:
                    raise Interrupted(stop.signum, _at(k, ts))
                if log is not None and log.error is not None:
                    log.raise_error("; stopped" + _at(k, ts))
                # a plant that stopped answering because of a condition (a command timeout
                # sends its EMCY, then no TPDO) says so: fail with it, not with silence
                self._emcy_seen = self._check_emcy(self._emcy_seen, k, ts)
                if waited > 1.0:
                    self._check_alive(k, ts)
                if waited > 10.0:
                    raise PlantLost(f"the plant sent no TPDO for SYNC {k} (t = {k * ts:.3f} s) "
                                    f"within 10 s although its heartbeat continues")


RUN_COLUMNS = 16     # float64 columns of a bus run (Ecu.run): 3 set-point, 13 of the rows


def run_periods(duration_s: float, period_s: float) -> int:
    """The SYNC periods of a run of `duration_s`; BenchError, before anything starts, when
    that is less than one period or more than the trace can hold in memory (the ECU
    keeps the whole trace in memory: `bench.signals.trace.max_rows`)."""
    from bench.signals.trace import ROW_COPIES, memory_available
    n = int(round(duration_s / period_s))
    if n < 1:
        raise BenchError(f"a run of {duration_s:g} s is shorter than one SYNC period "
                         f"({period_s * 1e3:g} ms)")
    avail = memory_available()
    limit = max_rows(RUN_COLUMNS, avail)
    if n > limit:
        per = 8 * RUN_COLUMNS * ROW_COPIES
        raise BenchError(
            f"a run of {duration_s:g} s (--duration, or the profile's own length) is "
            f"{n:,} SYNC periods, and the ECU keeps the "
            f"trace in memory ({per} bytes a period with the copies made to save it): half "
            f"the memory available now ({avail / 1e9:.1f} GB) holds {limit:,} periods, "
            f"{limit * period_s:,.0f} s; make shorter runs")
    return n
