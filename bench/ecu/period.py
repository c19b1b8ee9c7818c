"""The steps of one SYNC period of the ECU's control loop, and the loop's state.

Per period k (`bench.ecu.runloop.RunLoop.run` calls them in this order):
`sync` (SYNC and the set-points), `collect` (TPDO1-3 of this SYNC), `check` (another ECU,
a signal, a failed log), `control` (the demand as RPDO1, the plant's failing conditions)
and `end` (the period's frames into the rows, heartbeat, pacer, progress). The trace's
rows are those of the frames as logged (`bench.ecu.rowtap`), not the values the loop
held: a TPDO that missed its period in real time leaves NaN in that row (the controller
used the previous value), as in the decoded log."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import can
import numpy as np

from bench.ecu.errors import FAILING_BITS, BusLost, Interrupted, _at
from bench.ecu.rowtap import RowTap
from bench.ecu.signals import StopSignal
from bench.profiles.catalog import Profile
from bench.signals.trace import Trace
from bench.sim.control import Controller, ControllerParams
from ema_contract.frames import FrameError
from ema_contract.states import ControlWord, Pace, StatusWord
from plant_rt.pacing import RealtimePacer
from plant_rt.params import PlantParams

BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} {unit} [{elapsed}<{remaining}]"
"""The run's bar: simulated seconds as 9.98/15.00, not the float sum 9.984000000000002."""


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


def float32_limit(limit: float) -> float:
    """The largest float32 not above `limit` (a demand sent as float32 within it)."""
    v = np.float32(limit)
    if float(v) > limit:
        v = np.nextafter(v, np.float32(0.0))
    return float(v)


class PeriodSteps:
    """One run's control loop state (set-points, controller, row tap, latest TPDOs, pacer)
    and its steps per SYNC period, on the ECU `ecu` (a `bench.ecu.master.Ecu`: its
    link, claim and run-loop parts; typed Any, the Ecu imports this module)."""

    def __init__(self, ecu: Any, profile: Profile, params: PlantParams,
                 cparams: ControllerParams, pace: Pace, n: int, spin_us: int,
                 stop: StopSignal | None, stats: EcuStats) -> None:
        self.ecu, self.profile, self.params, self.cparams = ecu, profile, params, cparams
        self.pace, self.n, self.stop, self.stats = pace, n, stop, stats
        ts = self.ts = params.sim.sync_period_s
        self.t = np.arange(n) * ts
        self.sp_pos, self.sp_spd = profile.setpoints(self.t)
        self.mode = int(profile.mode)
        self.cpr = float(params.sensors.encoder_counts_per_rev)
        ctrl = self.ctrl = Controller(cparams)
        ctrl.step(0.0, 0.0, self.mode, 0.0, 0.0)   # load the compiled step before the clock runs
        ctrl.reset()
        self.tap = RowTap(ecu.frames, ecu._sync_max)
        self.spin_us = spin_us
        self.bar = None
        self.latest: dict[str, dict[str, Any]] = {}
        self.fresh: set[str] = set()
        self.tpdo1_seen = 0       # TPDO1s received in the run: the n-th answers SYNC n-1
        self.reset_k: int | None = None   # the period whose RPDO1 carried the fault reset
        self.emcy_seen = 0
        self.on_period: Callable[[int], None] | None = None
        self.bus_stamps = False   # the log in bus time (`bench.ecu.busclock`)

    def setup(self, progress: bool) -> None:
        """The progress bar, the pacer and the frames' encoders, just before the loop."""
        ecu, ts = self.ecu, self.ts
        if progress:
            from tqdm import tqdm
            self.bar = tqdm(total=round(self.n * ts, 3), unit="sim s", desc=self.profile.name,
                            leave=False, bar_format=BAR_FORMAT)
        self.pacer = RealtimePacer(ts, self.spin_us * 1e-6) if self.pace == Pace.REALTIME \
            else None
        # lockstep: the heartbeat on the SYNC grid (the plant counts its consumer time in
        # SYNC periods), and on the wall clock as well (while waiting, or a slow run)
        self.hb_every = max(1, round(ecu._hb_period / ts)) if self.pacer is None else 0
        fail_bits = 0
        for bit in FAILING_BITS:
            fail_bits |= int(bit)
        self.fail_bits = fail_bits
        self.limit_a = float32_limit(self.params.motor.current_max_a)
        self.enc_rpdo = ecu.frames.by_name["EMA_RPDO1"]
        self.enc_sp = ecu.frames.by_name["ECU_Setpoint"]
        self.cob_rpdo, self.cob_sp = ecu._cob["EMA_RPDO1"], ecu._cob["ECU_Setpoint"]
        self.enable = int(ControlWord.ENABLE)
        # the first RPDO sent also carries a fault-reset edge: it clears a command timeout
        # the node latched before the run (a stall during set-up, when no demand of this
        # run was in force), so that it is gone at the next SYNC, where the first demand
        # applies. In real time the first RPDO is sent in the first period whose TPDO set
        # has arrived, which on a loaded machine is not always period 0.
        self.first_control = self.enable | int(ControlWord.FAULT_RESET)
        self.timeout_bit = int(StatusWord.COMMAND_TIMEOUT)
        self.t_wall0 = time.perf_counter()
        self.last_bar = time.monotonic()

    def poll(self, timeout: float) -> None:
        """One frame from the bus (or none within `timeout`): monitored, a TPDO kept."""
        ecu = self.ecu
        try:
            msg = ecu.bus.recv(timeout=max(0.0, timeout))
        except (can.CanError, OSError, Exception) as exc:  # noqa: BLE001
            raise BusLost(f"the bus connection failed: {type(exc).__name__}: {exc}") \
                from None
        if msg is None:
            return
        ecu.frames_polled += 1
        ecu._monitor(msg)
        name = ecu._tpdo_names.get(msg.arbitration_id)
        if name is not None:
            try:
                decoded = ecu.frames.decode(msg)
            except FrameError:
                return
            self.latest[name] = decoded[1]  # type: ignore[index]
            self.fresh.add(name)
            if name == "EMA_TPDO1":
                self.tpdo1_seen += 1

    def drain(self, limit: int = 64) -> None:
        """Real time: the frames already received, without waiting. An ECU behind its
        releases (a loaded machine) found its window over at once and read nothing, so
        frames piled up and the plant's heartbeat went unseen until the run ended with
        "the plant stopped answering"; the newest values are the ones kept."""
        ecu = self.ecu
        for _ in range(limit):
            before = ecu.frames_polled
            self.poll(0.0)
            if ecu.frames_polled == before:
                return

    def sync(self, k: int) -> None:
        """Release period k: SYNC, then its set-points (known at its SYNC: sent while the
        plant answers, ECU TPDO, synchronous)."""
        ecu, frames = self.ecu, self.ecu.frames
        if self.pacer is not None:
            self.pacer.wait(self.poll)
        self.fresh.clear()
        ecu.log_clock.period(k)
        ecu._send_sync()
        ecu.send(can.Message(arbitration_id=self.cob_sp, is_extended_id=False,
                             data=self.enc_sp.encode({
                                 "SetpointPosition": frames.clamp(
                                     "ECU_Setpoint", "SetpointPosition", self.sp_pos[k]),
                                 "SetpointSpeed": frames.clamp(
                                     "ECU_Setpoint", "SetpointSpeed", self.sp_spd[k]),
                                 "Mode": self.mode}, strict=True)))

    def collect(self, k: int) -> None:
        """TPDO1-3 of SYNC k: waited for in lockstep, within 80 % of the period in real
        time (a late period counted, the plant's heartbeat checked every 50th)."""
        pacer, fresh = self.pacer, self.fresh
        if pacer is None:
            self.ecu._wait_tpdos(self.poll, fresh, k, self.ts)
            return
        window = pacer.release_ns + int(0.8 * pacer.period_ns)
        while len(fresh) < 3:
            left = (window - time.perf_counter_ns()) / 1e9
            if left <= 0:
                break
            self.poll(left)
        self.drain()
        if len(fresh) < 3:
            self.stats.late_tpdo += 1
            if k % 50 == 0:
                self.ecu._check_alive(k, self.ts)

    def check(self, k: int) -> None:
        """What happened during the period, before its row is recorded."""
        ecu, ts, stop, log = self.ecu, self.ts, self.stop, self.ecu.log
        if ecu.foreign is not None:
            ecu.check_foreign(f" at t = {k * ts:.3f} s, SYNC {k}")
        if stop is not None and stop.signum is not None:
            raise Interrupted(stop.signum, _at(k, ts))
        if log is not None and log.error is not None:
            log.raise_error("; stopped" + _at(k, ts))

    def control(self, k: int) -> None:
        """The demand of period k as RPDO1, the plant's failing conditions."""
        ecu, latest = self.ecu, self.latest
        t1, t2, t3 = latest["EMA_TPDO1"], latest["EMA_TPDO2"], latest["EMA_TPDO3"]
        pos = float(t3["LvdtPosition"])
        spd = float(t2["EncoderSpeed"])
        demand = self.ctrl.step(self.sp_pos[k], self.sp_spd[k], self.mode, pos, spd)
        # within the plant's own current limit (read back), so that a demand the
        # plant clamps (status bit 5, EMCY demand_invalid) is always a real fault
        limit_a = self.limit_a
        if demand > limit_a:
            demand = limit_a
        elif demand < -limit_a:
            demand = -limit_a
        demand32 = float(np.float32(demand))
        control, reset_k = self.enable, self.reset_k
        if reset_k is None:
            reset_k = self.reset_k = k
            control = self.first_control
        ecu.send(can.Message(arbitration_id=self.cob_rpdo, is_extended_id=False,
                             data=self.enc_rpdo.encode({
                                 "CurrentDemand": demand32, "ControlWord": control},
                                 strict=True)))
        word = int(t1["StatusWord"])
        self.stats.periods = k + 1
        fail = word & self.fail_bits
        # a command timeout alone is the pre-run latch until the status word answers a
        # SYNC after the fault reset: the (reset_k + 2)-th TPDO1 (the plant answers every
        # SYNC in order, so the count, not the wall clock, says which SYNC a word is from)
        if fail and (fail != self.timeout_bit or self.tpdo1_seen >= reset_k + 2):
            raise ecu._status_fault(word, k, self.ts)
        if len(ecu.emcy) != self.emcy_seen:
            self.emcy_seen = ecu._emcy_seen = ecu._check_emcy(self.emcy_seen, k, self.ts)

    def wait_first(self, k: int) -> None:
        """Real time, a period before the first TPDO set has arrived: no demand yet (the
        plant applies none), the heartbeat kept on the wall clock, the next release."""
        self.ecu.heartbeat()
        if self.pacer is not None:
            self.pacer.done()

    def end(self, k: int) -> None:
        """The period's frames into the rows, its heartbeat (on the SYNC grid in
        lockstep), pacer, callback, bar."""
        self.tap.drain()
        hb_every = self.hb_every
        self.ecu.heartbeat(force=bool(hb_every) and (k + 1) % hb_every == 0)
        if self.pacer is not None:
            self.pacer.done()
        if self.on_period is not None:
            self.on_period(k)
        bar = self.bar
        if bar is not None and (k & 0xFF) == 0:
            now = time.monotonic()
            if now - self.last_bar > 0.25:
                bar.update(round(k * self.ts - bar.n, 3))
                self.last_bar = now

    def close(self) -> None:
        """After the loop, whatever ended it: wall time, bar, the pacer's statistics."""
        stats, pacer, bar = self.stats, self.pacer, self.bar
        stats.wall_s = time.perf_counter() - self.t_wall0
        if bar is not None:
            bar.update(round(stats.periods * self.ts - bar.n, 3))
            bar.close()
        if pacer is not None:
            stats.sync_jitter_p50_us = pacer.lateness.percentile_us(50)
            stats.sync_jitter_p99_us = pacer.lateness.percentile_us(99)
            stats.sync_jitter_max_us = pacer.lateness.max_us
            stats.sync_deadline_misses = pacer.misses

    def trace(self) -> Trace:
        """The run's trace: the rows of the periods done (all of them:
        ``meta["complete"]``), assembled from the frames as logged, with what the
        assembler counted (``meta["bus_rows"]``)."""
        ecu, stats, m, n = self.ecu, self.stats, self.stats.periods, self.n
        cols = self.tap.columns(self.ts, self.cpr, m)
        profile = self.profile
        meta = {"source": "bus", "pace": Pace(self.pace).name.lower(), "profile": profile.name,
                "profile_kwargs": profile.kwargs, "fundamental_hz": profile.fundamental_hz,
                "params": self.params.to_dict(), "controller": asdict(self.cparams),
                "complete": m == n, "node_id": ecu.node_id, "ecu": asdict(stats),
                "emcy": list(ecu.emcy), "bus_rows": self.tap.counts(),
                "log_stamps": "bus" if self.bus_stamps else "wall"}
        return Trace(cols, meta)
