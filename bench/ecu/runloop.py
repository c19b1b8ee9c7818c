"""The ECU's control loop: one SYNC period after another, the trace of the run."""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import can
import numpy as np
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench import BenchError
from bench.control import Controller, ControllerParams
from bench.ecu.errors import (
    FAILING_BITS,
    FAILING_TEXT,
    REPORTING_EMCY,
    BusLost,
    Interrupted,
    PlantFault,
    PlantLost,
    _at,
    status_names,
)
from bench.ecu.signals import StopSignal
from bench.profiles import Profile
from bench.trace import Trace, max_rows
from ema_contract.frames import FrameError
from ema_contract.states import ControlWord, NMTCommand, Pace, StatusWord
from plant_rt.pacing import RealtimePacer
from plant_rt.params import PlantParams

TWO_PI = 2.0 * math.pi


@dataclass
class EcuStats:
    """What the ECU measured about the run."""
    periods: int = 0
    late_tpdo: int = 0            # periods whose TPDOs missed their window (realtime)
    wall_s: float = 0.0
    sync_jitter_p50_us: float = 0.0
    sync_jitter_p99_us: float = 0.0
    sync_jitter_max_us: float = 0.0
    sync_deadline_misses: int = 0
    frames_logged: int = 0



class RunLoop:
    """Mixin of `Ecu`: `run` a profile on the prepared node."""

    def run(self, profile: Profile, params: PlantParams, cparams: ControllerParams | None = None,
            pace: Pace = Pace.SYNC, duration_s: float | None = None, progress: bool = False,
            spin_us: int = 200, on_period: Callable[[int], None] | None = None,
            stop: StopSignal | None = None) -> Trace:
        """Run `profile` on the prepared plant; returns the trace (partial on error: the
        error is raised after the trace is stored in `self.partial`, and the node is set
        PRE-OPERATIONAL). The run fails (`PlantFault`) as soon as the plant reports a
        condition that changes its behaviour (FAILING_BITS, any EMCY outside
        REPORTING_EMCY), another ECU shows up (`ForeignEcu`), the log cannot be written
        (`LogWriteError`) or `stop` records a signal (`Interrupted`)."""
        ts = params.sim.sync_period_s
        cparams = cparams or ControllerParams(sample_period_s=ts)
        if not math.isclose(cparams.sample_period_s, ts):
            raise BenchError(f"controller period {cparams.sample_period_s} s differs from the "
                             f"plant's SYNC period {ts} s")
        dur = profile.duration_s if duration_s is None else duration_s
        n = run_periods(dur, ts)
        t = np.arange(n) * ts
        sp_pos, sp_spd = profile.setpoints(t)
        mode = int(profile.mode)
        cpr = float(params.sensors.encoder_counts_per_rev)
        ctrl = Controller(cparams)
        ctrl.step(0.0, 0.0, mode, 0.0, 0.0)   # load the compiled step before the clock runs
        ctrl.reset()
        rows = {k: np.full(n, np.nan) for k in (
            "current_demand_a", "current_a", "motor_speed_rad_s", "motor_angle_rad",
            "position_m", "winding_temperature_k", "load_force_n", "status_word",
            "bus_time_s")}
        stats = EcuStats()
        self.partial = None
        self._stop = stop
        k = 0
        bar = None
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=round(n * ts, 3), unit="sim s", desc=profile.name, leave=False)
        latest: dict[str, dict[str, Any]] = {}
        fresh: set[str] = set()
        frames = self.frames
        bus = self.bus
        log = self.log
        tpdo_names = self._tpdo_names
        monitor = self._monitor
        pacer = RealtimePacer(ts, spin_us * 1e-6) if pace == Pace.REALTIME else None
        # lockstep: the heartbeat on the SYNC grid (the plant counts its consumer time in
        # SYNC periods), and on the wall clock as well (while waiting, or a slow run)
        hb_every = max(1, round(self._hb_period / ts)) if pacer is None else 0
        fail_bits = 0
        for bit in FAILING_BITS:
            fail_bits |= int(bit)
        limit_a = _float32_limit(params.motor.current_max_a)
        enc_rpdo = frames.by_name["EMA_RPDO1"]
        enc_sp = frames.by_name["ECU_Setpoint"]
        cob_rpdo, cob_sp = self._cob["EMA_RPDO1"], self._cob["ECU_Setpoint"]
        enable = int(ControlWord.ENABLE)
        # the first RPDO also carries a fault-reset edge: it clears a command timeout the
        # node latched before the run (a stall during set-up, when no demand of this run
        # was in force), so that it is gone at SYNC 1, where the first demand applies
        first_control = enable | int(ControlWord.FAULT_RESET)
        timeout_bit = int(StatusWord.COMMAND_TIMEOUT)
        t_wall0 = time.perf_counter()
        t_first_sync: float | None = None
        last_bar = time.monotonic()
        error: BaseException | None = None

        def poll(timeout: float) -> None:
            try:
                msg = bus.recv(timeout=max(0.0, timeout))
            except (can.CanError, OSError, Exception) as exc:  # noqa: BLE001
                raise BusLost(f"the bus connection failed: {type(exc).__name__}: {exc}") \
                    from None
            if msg is None:
                return
            monitor(msg)
            name = tpdo_names.get(msg.arbitration_id)
            if name is not None:
                try:
                    decoded = frames.decode(msg)
                except FrameError:
                    return
                latest[name] = decoded[1]  # type: ignore[index]
                fresh.add(name)

        self.unlisten()
        # keep full garbage collections (tens of ms with numba and scipy loaded) out of
        # the control loop: what exists now is not scanned again until the run ends
        gc.collect()
        gc.freeze()
        if stop is not None:
            stop.defer = True
        try:
            self.stop_heartbeat()
            self.check_foreign()
            self.check_receive()
            self._hb_next = 0.0
            self.heartbeat()
            self._started = True
            self.nmt(NMTCommand.START)
            emcy_seen = self._emcy_seen = len(self.emcy)
            if pacer is not None:
                pacer.start(5 * ts)
            for k in range(n):
                if pacer is not None:
                    pacer.wait(poll)
                fresh.clear()
                self._send_sync()
                # the set-points of this period are known at its SYNC: send them while
                # the plant answers (ECU TPDO, synchronous)
                self.send(can.Message(arbitration_id=cob_sp, is_extended_id=False,
                                      data=enc_sp.encode({
                                          "SetpointPosition": frames.clamp(
                                              "ECU_Setpoint", "SetpointPosition", sp_pos[k]),
                                          "SetpointSpeed": frames.clamp(
                                              "ECU_Setpoint", "SetpointSpeed", sp_spd[k]),
                                          "Mode": mode}, strict=True)))
                if t_first_sync is None:
                    t_first_sync = time.perf_counter()
                rows["bus_time_s"][k] = time.perf_counter() - t_first_sync
                if pacer is None:
                    self._wait_tpdos(poll, fresh, k, ts)
                else:
                    window = pacer.release_ns + int(0.8 * pacer.period_ns)
                    while len(fresh) < 3:
                        left = (window - time.perf_counter_ns()) / 1e9
                        if left <= 0:
                            break
                        poll(left)
                    if len(fresh) < 3:
                        stats.late_tpdo += 1
                        if k % 50 == 0:
                            self._check_alive(k, ts)
                # what happened during the period, before its row is recorded
                if self.foreign is not None:
                    self.check_foreign(f" at t = {k * ts:.3f} s, SYNC {k}")
                if stop is not None and stop.signum is not None:
                    raise Interrupted(stop.signum, _at(k, ts))
                if log is not None and log.error is not None:
                    log.raise_error("; stopped" + _at(k, ts))
                if pacer is not None and len(latest) < 3:
                    pacer.done()
                    continue
                t1, t2, t3 = latest["EMA_TPDO1"], latest["EMA_TPDO2"], latest["EMA_TPDO3"]
                pos = float(t3["LvdtPosition"])
                spd = float(t2["EncoderSpeed"])
                demand = ctrl.step(sp_pos[k], sp_spd[k], mode, pos, spd)
                # within the plant's own current limit (read back), so that a demand the
                # plant clamps (status bit 5, EMCY demand_invalid) is always a real fault
                if demand > limit_a:
                    demand = limit_a
                elif demand < -limit_a:
                    demand = -limit_a
                demand32 = float(np.float32(demand))
                self.send(can.Message(arbitration_id=cob_rpdo, is_extended_id=False,
                                      data=enc_rpdo.encode({
                                          "CurrentDemand": demand32,
                                          "ControlWord": enable if k else first_control},
                                          strict=True)))
                word = int(t1["StatusWord"])
                rows["current_demand_a"][k] = demand32
                rows["current_a"][k] = t1["MotorCurrent"]
                rows["status_word"][k] = word
                rows["motor_speed_rad_s"][k] = spd
                rows["motor_angle_rad"][k] = t2["EncoderAngle"] * TWO_PI / cpr
                rows["position_m"][k] = pos
                rows["winding_temperature_k"][k] = t3["WindingTemperature"]
                rows["load_force_n"][k] = t3["LoadForce"]
                stats.periods = k + 1
                if word & fail_bits and (k or word & fail_bits != timeout_bit):
                    raise self._status_fault(word, k, ts)
                if len(self.emcy) != emcy_seen:
                    emcy_seen = self._emcy_seen = self._check_emcy(emcy_seen, k, ts)
                self.heartbeat(force=bool(hb_every) and (k + 1) % hb_every == 0)
                if pacer is not None:
                    pacer.done()
                if on_period is not None:
                    on_period(k)
                if bar is not None and (k & 0xFF) == 0:
                    now = time.monotonic()
                    if now - last_bar > 0.25:
                        bar.update(round(k * ts - bar.n, 3))
                        last_bar = now
        except BaseException as exc:  # noqa: BLE001 - stored, re-raised below
            error = exc
        finally:
            if stop is not None:
                stop.defer = False
            gc.unfreeze()
            stats.wall_s = time.perf_counter() - t_wall0
            if bar is not None:
                bar.update(round(stats.periods * ts - bar.n, 3))
                bar.close()
            if pacer is not None:
                stats.sync_jitter_p50_us = pacer.lateness.percentile_us(50)
                stats.sync_jitter_p99_us = pacer.lateness.percentile_us(99)
                stats.sync_jitter_max_us = pacer.lateness.max_us
                stats.sync_deadline_misses = pacer.misses
        m = stats.periods
        cols = {"t_s": t[:m], "setpoint_position_m": sp_pos[:m],
                "setpoint_speed_rad_s": sp_spd[:m], "mode": np.full(m, float(mode))}
        cols.update({k_: v[:m] for k_, v in rows.items()})
        meta = {"source": "bus", "pace": Pace(pace).name.lower(), "profile": profile.name,
                "profile_kwargs": profile.kwargs, "fundamental_hz": profile.fundamental_hz,
                "params": params.to_dict(), "controller": asdict(cparams),
                "complete": m == n, "node_id": self.node_id, "ecu": asdict(stats),
                "emcy": list(self.emcy)}
        trace = Trace(cols, meta)
        self.partial = trace
        if error is not None:
            trace.meta["error"] = str(error) or type(error).__name__
            if self.log is not None:
                stats.frames_logged = self.log.count
            trace.meta["ecu"] = asdict(stats)
            self.abort()
            raise error
        self._finish(trace, stats)
        return trace

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

    def _finish(self, trace: Trace, stats: EcuStats) -> None:
        """Orderly end: drive to PRE-OPERATIONAL, stop heartbeat monitoring, counters."""
        self.listen()
        try:
            self.nmt(NMTCommand.ENTER_PRE_OPERATIONAL)
            self.remote.sdo[0x1016][1].raw = 0   # orderly log-out: stop consuming our heartbeat
            trace.meta["plant_counters"] = self.read_status()
        except (BenchError, SdoAbortedError, SdoCommunicationError) as exc:
            trace.meta["plant_counters"] = {"error": str(exc)}
        time.sleep(0.02)   # let the last answers reach the log
        trace.meta["emcy"] = list(self.emcy)
        if self.log is not None:
            stats.frames_logged = self.log.count
        trace.meta["ecu"] = asdict(stats)

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


def _float32_limit(limit: float) -> float:
    """The largest float32 not above `limit` (a demand sent as float32 within it)."""
    v = np.float32(limit)
    if float(v) > limit:
        v = np.nextafter(v, np.float32(0.0))
    return float(v)


RUN_COLUMNS = 13     # float64 columns of a bus run's trace (Ecu.run)


def run_periods(duration_s: float, period_s: float) -> int:
    """The SYNC periods of a run of `duration_s`; BenchError, before anything starts, when
    that is less than one period or more than the trace can hold in memory (the ECU
    keeps the whole trace in memory: `bench.trace.max_rows`)."""
    from bench.trace import ROW_COPIES, memory_available
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
