"""The plant as a CANopen node: NMT, heartbeat, SYNC-driven PDOs, SDO parameters, EMCY.

One thread does everything (receive, SDO, PDOs, stepping), so there is no lock, no
GIL hand-over between a receive thread and the pacer, and the lockstep mode is
deterministic. The CiA 301 part every node on the bench's bus shares (NMT state machine,
heartbeat producer, the SDO server over the object dictionary of `dbc/ema.eds`, SYNC
and frame dispatch, the loop and its frame drain) is `ema_contract.node.CanopenNode`;
the plant's PDOs, EMCY, heartbeat consumer and objects are handled here with the frame
layouts of `dbc/ema.dbc` (cantools). See docs/bus.md for why not `durand`.

Timing (CiA 301 synchronous PDOs, transmission type 1):

- at a SYNC the node latches the last RPDO received (the ECU's demand of the previous
  period), sends TPDO1-3 with the sensors sampled at that instant, and
- `--pace sync`: integrates exactly one SYNC period holding the latched demand
  (lockstep: deterministic under any load, as fast as the bus allows);
- `--pace realtime`: the plant integrates one period per wall-clock release of its own
  absolute-deadline pacer (`plant_rt.pacing`), holding whatever demand was latched at
  the last SYNC; a late or silent ECU leaves the last command in force until its
  heartbeat is declared lost. As a drive synchronises its loop to SYNC, the pacer's
  phase is slowly pulled to SYNC_PHASE of a period after each SYNC, so that SYNC
  handling never falls into the pacer's spin window or the step.

The simulated world only advances in OPERATIONAL: an idle node costs no CPU.

Time bases: in lockstep the node's timers count SYNC periods, not wall time.
The heartbeat consumer (0x1016) declares the ECU lost after more than consumer time /
SYNC period SYNCs without its heartbeat (a late heartbeat cannot latch a timeout: no
SYNC, no motion); in real time it runs on the wall clock. A timeout follows the error
behaviour object 0x1029 (default 0: OPERATIONAL -> PRE-OPERATIONAL). The EMCY inhibit
time (0x1015) and the log rate limit run on the node clock (`PlantNode.node_time`): SYNC
time in lockstep while OPERATIONAL (EMCYs fall on the same SYNCs in every run), the wall
clock otherwise.

The node is one class, `PlantNode`, on `ema_contract.node.CanopenNode`, written in six
modules by job: this one (the plant's NMT transitions, SYNC handling, PDOs, node clock,
real-time loop turn), `plant_rt.emcy` (EMCY producer), `plant_rt.heartbeat` (heartbeat
consumer, error behaviour), `plant_rt.sdoobjects` (SDO object callbacks) as its mixins, and
`plant_rt.ratelimit` (EMCY inhibit queue, log limiter) and `plant_rt.nodebase` (counters,
command, the interface the parts use) which they build on.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import can

from ema_contract.frames import FrameError, Frames, load_od
from ema_contract.node import IDLE_POLL_S, CanopenNode
from ema_contract.states import ControlWord, NMTState, Pace, Status, StatusWord
from plant_rt.emcy import EMCY_CONDITIONS, ERR_COMMUNICATION, EmcyProducer, EmcyState
from plant_rt.heartbeat import Heartbeat
from plant_rt.model import Plant, warm_up
from plant_rt.nodebase import Command, Counters
from plant_rt.pacing import LatenessStats, RealtimePacer
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import PlantParams
from plant_rt.ratelimit import Inhibit, LogLimiter
from plant_rt.sdoobjects import SdoObjects

log = logging.getLogger("plant_rt.node")

TWO_PI = 2.0 * math.pi

_COMMAND_TIMEOUT = int(StatusWord.COMMAND_TIMEOUT)
_DEMAND_CLAMPED = int(StatusWord.DEMAND_CLAMPED)
_ENABLED = int(StatusWord.ENABLED)
_RPDO_MISSING = int(StatusWord.RPDO_MISSING)
_DEADLINE_MISS = int(StatusWord.DEADLINE_MISS)
_ENABLE = int(ControlWord.ENABLE)
# real-time pacer: releases locked this fraction of a period after a SYNC has been handled
SYNC_PHASE = 0.3


class PlantNode(EmcyProducer, Heartbeat, SdoObjects, CanopenNode):
    """The actuator node on `bus`, integrating `Plant(params)` (see module docstring)."""

    logger = log

    def __init__(self, bus: can.BusABC, params: PlantParams | None = None,
                 pace: Pace = Pace.REALTIME, node_id: int | None = None,
                 ecu_id: int | None = None, spin_us: int = 200,
                 serial: int | None = None,
                 plant_factory: Callable[[PlantParams], Plant] = Plant,
                 clock: Callable[[], float] = time.monotonic) -> None:
        frames = Frames(node_id, ecu_id)
        self.counters = Counters()
        CanopenNode.__init__(self, bus, frames, load_od(frames.node_id), clock,
                             self.counters)
        self.param_objects = ParamObjects(self.od)
        self._status_keys = self._record_keys("node_status")
        self._control_keys = self._record_keys("node_control")
        self._tx_keys = self._record_keys("tx_process_data")
        self._rx_keys = self._record_keys("rx_process_data")
        self._plant_factory = plant_factory
        self.startup_params = params or PlantParams()
        # the actuator's serial number, identity object 0x1018 sub 4 (default: the EDS's)
        self.serial = int(self.od[0x1018][4].default) if serial is None else int(serial)
        if not 0 <= self.serial <= 0xFFFFFFFF:
            raise ValueError(f"serial number {self.serial} is not an UNSIGNED32 "
                             "(0..4294967295)")
        self.params = self.startup_params
        warm_up(self.params, plant_factory)     # before the bus sees it: see warm_up
        self.plant = plant_factory(self.params)
        self.startup_pace = Pace(pace)
        self.pace = self.startup_pace
        self.spin_us = int(spin_us)
        self.pending = Command()
        self.latched = Command()
        self.applied_a = 0.0
        self._rpdo_fresh = False
        self._synced_since_start = False
        self._last_control = ControlWord.NONE
        self._last_sync_counter: int | None = None
        self._sync_max = int(self.od[0x1019].default)
        self._error_behaviour = int(self.od[0x1029][1].default)
        self._syncs_since_hb: int | None = None   # SYNCs received since the ECU heartbeat
        self._timeout = False
        self._rpdo_missing_flag = False
        self._emcy = EmcyState()
        # node clock (see node_time): SYNC time, and the wall/SYNC base and its offset
        self._sync_time_s = 0.0
        self._tbase_sync = False
        self._tbase_offset_s = 0.0
        self._emcy_inhibit = Inhibit(0.0)
        self._log = LogLimiter(log, 0.0)
        self._set_emcy_inhibit(int(self.od[0x1015].default))
        self._pdo_len_bad = False
        self._pacer = self._new_pacer()
        self.step_stats = LatenessStats()
        self._last_process: dict[str, float | int] | None = None
        self._sensor_cache: tuple[dict[str, float | int], list[can.Message], int] | None = None
        self.on_frame(self.frames.cob["EMA_RPDO1"], self._on_rpdo)

    # -- helpers ------------------------------------------------------------------------
    def _record_keys(self, name: str) -> dict[str, tuple[int, int]]:
        rec = self.od[name]
        return {var.name: (rec.index, sub) for sub, var in rec.subindices.items() if sub}

    def _new_pacer(self) -> RealtimePacer:
        return RealtimePacer(self.params.sim.sync_period_s, self.spin_us * 1e-6)

    @property
    def period_s(self) -> float:
        return self.params.sim.sync_period_s

    def node_time(self) -> float:
        """The clock of the node's EMCY inhibit time and log rate limit (s): SYNC time (the
        SYNC periods received) in lockstep while OPERATIONAL, the wall clock otherwise;
        continuous when the base changes (call it right after a state or pace change)."""
        sync_base = self.pace == Pace.SYNC and self.state == NMTState.OPERATIONAL
        raw = self._sync_time_s if sync_base else self.clock()
        if sync_base != self._tbase_sync:
            before = self.clock() if sync_base else self._sync_time_s
            self._tbase_offset_s += before - raw
            self._tbase_sync = sync_base
        return raw + self._tbase_offset_s

    def note(self, level: int, fmt: str, *args: object, exc_info: bool = False) -> None:
        """A log line, rate-limited on the node clock (`plant_rt.ratelimit.LogLimiter`)."""
        self._log.log(self.node_time(), level, fmt, *args, exc_info=exc_info)

    # -- life cycle ---------------------------------------------------------------------
    def boot(self) -> None:
        """Power-on / reset: boot-up frame, then PRE-OPERATIONAL with heartbeat."""
        super().boot()
        self.note(logging.INFO, "node 0x%02X booted, PRE-OPERATIONAL", self.node_id)

    def on_reset_node(self) -> None:
        """NMT reset node: parameters back to their start-up values, plant at t = 0."""
        self.params = self.startup_params
        self.pace = self.startup_pace
        self.plant = self._plant_factory(self.params)
        self._sensor_cache = None

    def on_reset_communication(self) -> None:
        # EMCYs still waiting for the inhibit time belong to the session the reset ends:
        # sent now, before the boot-up, never after it; the new session starts unthrottled
        self._send_emcy(self._emcy_inhibit.drain())
        self._error_behaviour = int(self.od[0x1029][1].default)
        self._set_emcy_inhibit(int(self.od[0x1015].default))
        self.counters.reset()
        self.step_stats.reset()
        self._pacer = self._new_pacer()
        self.pending = Command()
        self.latched = Command()
        self.applied_a = 0.0
        self._timeout = False
        self._syncs_since_hb = None
        self._last_sync_counter = None
        self._emcy = EmcyState()
        self._pdo_len_bad = False

    def set_state(self, new: NMTState) -> None:
        if new == self.state:
            return
        self.note(logging.INFO, "NMT %s -> %s", self.state.name, new.name)
        if new == NMTState.OPERATIONAL:
            self._synced_since_start = False
            self._rpdo_fresh = False
            self.pending = Command()
            self.latched = Command()
            self.applied_a = 0.0
            self._pacer = self._new_pacer()
            self._pacer.start(self.period_s)
        elif self.state == NMTState.OPERATIONAL:
            self.applied_a = 0.0          # leaving OPERATIONAL disables the drive
            self.latched = Command()
        super().set_state(new)
        self.node_time()                  # the node clock may change its base here

    # -- frames -------------------------------------------------------------------------
    def on_bad_frame(self, msg: can.Message, exc: FrameError) -> None:
        super().on_bad_frame(msg, exc)
        if msg.arbitration_id == self.frames.cob["EMA_RPDO1"] and not self._pdo_len_bad:
            self._pdo_len_bad = True
            self.emcy("pdo_length", ERR_COMMUNICATION)

    def _on_rpdo(self, msg: can.Message) -> None:
        _, sig = self.frames.decode(msg)  # type: ignore[misc]
        self._pdo_len_bad = False
        if self.state != NMTState.OPERATIONAL:
            return
        demand = float(sig["CurrentDemand"])
        control = ControlWord(int(sig["ControlWord"]) & (ControlWord.ENABLE
                                                         | ControlWord.FAULT_RESET))
        limit = self.params.motor.current_max_a
        invalid = False
        if not math.isfinite(demand):
            demand, invalid = 0.0, True
        elif abs(demand) > limit:
            demand, invalid = math.copysign(limit, demand), True
        if invalid:
            self.counters.demands_invalid += 1
        if (control & ControlWord.FAULT_RESET) and not (self._last_control
                                                         & ControlWord.FAULT_RESET):
            self._fault_reset()
        self._last_control = control
        self.pending = Command(demand, control, invalid)
        self._rpdo_fresh = True

    def on_sync(self, msg: can.Message) -> None:
        c = self.counters
        c.sync_received += 1
        self._sync_time_s += self.period_s
        if len(msg.data) == 1:
            counter = int(msg.data[0])
            last = self._last_sync_counter
            if last is not None and counter != (last % self._sync_max) + 1:
                c.sync_counter_gaps += 1
            self._last_sync_counter = counter
        if self._syncs_since_hb is not None:
            self._syncs_since_hb += 1
            if self.pace == Pace.SYNC and not self._ecu_alive() and not self._timeout:
                self._consumer_timed_out()
        if self.state != NMTState.OPERATIONAL:
            return
        # latch the command received since the previous SYNC (RPDO applied at this SYNC)
        if self._rpdo_fresh:
            self.latched = self.pending
            self._rpdo_fresh = False
            self._rpdo_missing_flag = False
        elif self._synced_since_start:
            c.rpdo_missing += 1
            self._rpdo_missing_flag = True
        self._synced_since_start = True
        self.applied_a = self._applied_demand()
        self.transmit_tpdos()
        if self.pace == Pace.SYNC:
            self._step()
        else:
            # keep the SYNC (and the TPDOs it triggers) out of the pacer's spin window and
            # step: lock the release phase SYNC_PHASE of a period after the SYNC arrival
            self._pacer.discipline(time.perf_counter_ns(),
                                   int(SYNC_PHASE * self._pacer.period_ns))

    def _applied_demand(self) -> float:
        cmd = self.latched
        if self._timeout or not (cmd.control & ControlWord.ENABLE):
            return 0.0
        return cmd.demand_a

    # -- process data ---------------------------------------------------------------------
    def status_word(self, plant_status: int) -> int:
        """The TPDO1 status word (bits of `StatusWord`) for the plant status now."""
        st = int(plant_status) & 0xF
        if self._timeout:
            st |= _COMMAND_TIMEOUT
        if self.latched.invalid:
            st |= _DEMAND_CLAMPED
        if (self.state == NMTState.OPERATIONAL and not self._timeout
                and self.latched.control & _ENABLE):
            st |= _ENABLED
        if self._rpdo_missing_flag:
            st |= _RPDO_MISSING
        if self.pace == Pace.REALTIME and self._pacer.last_missed:
            st |= _DEADLINE_MISS
        return st

    def _sensors(self) -> tuple[dict[str, float | int], list[can.Message], int]:
        """(sensor signal values, encoded TPDO2 and TPDO3, plant status) for the plant's
        state now. Cached until the plant moves, so in lockstep the encoding happens
        right after the step, while the ECU computes, not after the next SYNC."""
        if self._sensor_cache is None:
            m = self.plant.measure()
            f = self.frames
            cpr = self.params.sensors.encoder_counts_per_rev
            angle = m.motor_angle_rad
            counts = round(angle * cpr / TWO_PI) if math.isfinite(angle) else 0
            v: dict[str, float | int] = {
                "MotorCurrent": f.clamp("EMA_TPDO1", "MotorCurrent", m.current_a),
                "EncoderAngle": int(f.clamp("EMA_TPDO2", "EncoderAngle", counts)),
                "EncoderSpeed": f.clamp("EMA_TPDO2", "EncoderSpeed", m.motor_speed_rad_s),
                "LvdtPosition": f.clamp("EMA_TPDO3", "LvdtPosition", m.position_m),
                "WindingTemperature": f.clamp("EMA_TPDO3", "WindingTemperature",
                                              m.temperature_k),
                "LoadForce": f.clamp("EMA_TPDO3", "LoadForce", m.load_n),
            }
            msgs = [f.encode(name, {s.name: v[s.name] for s in f.by_name[name].signals})
                    for name in ("EMA_TPDO2", "EMA_TPDO3")]
            self._sensor_cache = (v, msgs, int(m.status))
        return self._sensor_cache

    def process_values(self) -> dict[str, float | int]:
        """The TPDO signals for the plant's sensors now (clamped to the DBC ranges)."""
        v, _, status = self._sensors()
        return {**v, "StatusWord": self.status_word(status)}

    def transmit_tpdos(self) -> None:
        """TPDO1 (current, status word), TPDO2 (encoder), TPDO3 (LVDT, temperature, load)."""
        v, msgs, status = self._sensors()
        word = self.status_word(status)
        self.send(self.frames.encode("EMA_TPDO1", {"MotorCurrent": v["MotorCurrent"],
                                                  "StatusWord": word}))
        for msg in msgs:
            self.send(msg)
        self._last_process = {**v, "StatusWord": word}

    def _step(self) -> None:
        t0 = time.perf_counter_ns()
        self.plant.step(self.applied_a)
        self.step_stats.add(time.perf_counter_ns() - t0)
        self._sensor_cache = None
        self.counters.cycles += 1
        self._check_conditions()
        self._sensors()             # encode the next TPDOs now, off the SYNC's path

    # -- timers ---------------------------------------------------------------------------
    def on_timers(self, now: float, nxt: float) -> float:
        """The real-time heartbeat consumer, EMCYs and log lines whose inhibit time has
        ended (after the heartbeat producer, `CanopenNode.timers`)."""
        nxt = self._consumer_timer(now, nxt)
        t = self.node_time()
        self._send_due_emcy(t)
        self._log.flush(t)
        if self._emcy_inhibit.pending:
            nxt = min(nxt, self._emcy_inhibit.next_s() - t)
        return nxt

    # -- main loop ------------------------------------------------------------------------
    def serve_once(self) -> None:
        """Real time in OPERATIONAL: wait for the pacer's release serving the bus, drain
        the frames received meanwhile, step; otherwise wait for a frame."""
        if self.pace == Pace.REALTIME and self.state == NMTState.OPERATIONAL:
            pacer = self._pacer
            pacer.wait(self.poll)
            self.drain()
            if self.state != NMTState.OPERATIONAL or self.pace != Pace.REALTIME:
                return       # a frame handled while waiting changed the state
            self._step()
            pacer.done()
        else:
            self.poll(IDLE_POLL_S)

    def run(self, duration_s: float | None = None,
            alive: Callable[[], bool] | None = None) -> None:
        """`serve()`: boot, then serve the bus until `stop()`, for `duration_s` of wall
        time, or until `alive()` (checked every 0.25 s) returns False."""
        self.serve(duration_s, alive)


def plant_status_names(word: int) -> list[str]:
    """Names of the bits set in a status word (for messages)."""
    return [f.name.lower() for f in StatusWord if f and word & f and f.name]


# EMCY_CONDITIONS and LogLimiter are also importable from here, where they used to live
__all__ = ["PlantNode", "Counters", "Status", "plant_status_names", "EMCY_CONDITIONS",
           "LogLimiter"]
