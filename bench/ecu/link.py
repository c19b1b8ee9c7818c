"""The ECU on the bus: sends, the frame monitor, NMT and the ECU's heartbeat."""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.network import MessageListener

from bench import BenchError
from bench.ecu.busclock import LogClock
from bench.ecu.errors import BusLost
from bench.ecu.logwriter import _Log
from bench.ecu.nodeinfo import NodeInfo
from bench.ecu.rowtap import RowTap
from bench.ecu.sdoclient import SDO_ATTEMPTS, SDO_TIMEOUT_S, EcuRemoteNode
from bench.ecu.signals import StopSignal
from bench.signals.trace import Trace
from ema_contract.frames import FrameError, Frames, load_od
from ema_contract.states import NMTCommand, NMTState, Pace
from plant_rt.paramobjects import ParamObjects

# canopen logs SDO aborts and timeouts it reports anyway as exceptions; keep stderr clean
logging.getLogger("canopen").setLevel(logging.CRITICAL)
TPDOS = ("EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3")
# frames only the ECU sends: seen from another producer, another ECU drives the node
ECU_FRAMES = ("SYNC", "EMA_RPDO1", "ECU_Setpoint", "ECU_Heartbeat")


class EcuLink:
    """The ECU's side of the bus: its state, sending (logged), the receive thread with the
    frame monitor (log, plant heartbeat, EMCY), NMT and its own heartbeat."""

    def __init__(self, bus: can.BusABC, node_id: int | None = None, ecu_id: int | None = None,
                 log_path: str | Path | None = None, echo: bool = False,
                 sdo_timeout_s: float = SDO_TIMEOUT_S, sdo_attempts: int = SDO_ATTEMPTS
                 ) -> None:
        self.bus = bus
        self.frames = Frames(node_id, ecu_id)
        self.node_id = self.frames.node_id
        self.ecu_id = self.frames.ecu_id
        self.od = load_od(self.node_id)
        # canopen's sends are logged too (_TeeBus forwards everything else to `bus`)
        self.network = canopen.Network(_TeeBus(bus, self))  # type: ignore[arg-type]
        self.remote = EcuRemoteNode(self.node_id, self.od)
        self.network.add_node(self.remote)
        self.remote.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
        self.sdo_attempts = max(1, int(sdo_attempts))
        self.sdo_retries = 0       # transfers started again after a missing answer
        self.param_objects = ParamObjects(self.od)
        self.log = _Log(Path(log_path)) if log_path else None
        self.log_clock = LogClock()        # the log's stamps: wall, or bus time in lockstep
        self.tap: RowTap | None = None     # the run's rows (`RunLoop.run`), fed like the log
        self._record_lock = threading.Lock()   # log and rows see the frames in one order
        self.echo = echo               # the bus returns our own frames (for the log)
        self.emcy: list[dict[str, Any]] = []
        self._emcy_seen = 0        # EMCYs already checked by the run (_check_emcy)
        self.plant_state: NMTState | None = None
        self.plant_hb: float | None = None
        self.bootups = 0
        self.frames_polled = 0     # frames the run loop read (`PeriodSteps.poll`)
        self.run_pace: Pace | None = None    # the run's pace and why (`Ecu.prepare`)
        self.pace_source = ""
        self._notifier: can.Notifier | None = None
        self._sync_counter = 0
        self._sync_max = int(self.od[0x1019].default)
        self._hb_period = self.frames.cycle_time_ms("ECU_Heartbeat") / 1000.0
        self._hb_next = 0.0
        self._cob = self.frames.cob
        self._tpdo_names = {self._cob[n]: n for n in TPDOS}
        self._hb_cob = self._cob["EMA_Heartbeat"]
        self._emcy_cob = self._cob["EMA_EMCY"]
        self._clock = time.monotonic
        self._t0_wall = time.time()
        self.node_info = NodeInfo()
        self._present: dict[tuple[int, int], bool] = {}   # (index, sub) -> the node has it
        self._absent_index: set[int] = set()                # whole objects it does not have
        self._missing: dict[str, None] = {}                 # labels of objects it lacks
        # claim on the node, foreign producers, receive errors, abort
        self.partial: Trace | None = None
        self._ecu_cobs = {self._cob[n]: n for n in ECU_FRAMES}
        self._own_echo: Counter[tuple[int, bytes]] = Counter()   # sent, echo not yet seen
        self.foreign: tuple[str, float] | None = None   # (frame name, ECU time seen)
        self.foreign_seen: dict[str, float] = {}         # every kind seen, first time
        self.rx_error: Exception | None = None           # a receive-thread failure
        self._listen_t0: float | None = None
        self._claimed = False      # the node is ours (claim() passed): abort() may act
        self._started = False      # run() sent NMT START
        self._aborted = False
        self._setup_hb: tuple[threading.Thread, threading.Event] | None = None
        self._stop: StopSignal | None = None

    # -- frames ---------------------------------------------------------------------------
    def send(self, msg: can.Message) -> None:
        self._log_sent(msg)
        if self.echo and msg.arbitration_id in self._ecu_cobs:
            self._own_echo[(msg.arbitration_id, bytes(msg.data))] += 1
        try:
            self.bus.send(msg)
        except (can.CanError, OSError) as exc:
            raise BusLost(f"cannot send on the bus: {exc}") from None

    def _log_sent(self, msg: can.Message) -> None:
        """Record an own frame just before it goes out, so that an answer (received on
        the notifier thread) can never precede its request in the log."""
        if not self.echo:
            msg.is_rx = False
            self._record(msg)

    def _record(self, msg: can.Message) -> None:
        """A frame for the log and the run's rows, in one order whatever the thread, and
        stamped as it is recorded (as candump stamps at reception): the bus's stamp of a
        received frame is earlier than that of an own frame the main thread logged while
        the frame waited for the receive thread, so the log's stamps went backwards."""
        log, tap = self.log, self.tap
        if log is None and tap is None:
            return
        with self._record_lock:
            msg.timestamp = self.log_clock.stamp(msg)
            if log is not None:
                log.on_message_received(msg)
            if tap is not None:
                tap.append(msg)

    def _on_ecu_frame(self, msg: can.Message) -> None:
        """A frame only an ECU sends (SYNC, set-point, RPDO1, ECU heartbeat): `EcuClaim`
        tells our own echo from another ECU."""

    def _monitor(self, msg: can.Message) -> None:
        """Record a received frame and track the plant's heartbeat and EMCY."""
        self._record(msg)
        cid = msg.arbitration_id
        if cid == self._hb_cob and len(msg.data) == 1:
            state = int(msg.data[0]) & 0x7F
            self.plant_hb = self._clock()
            if state == NMTState.BOOT_UP:
                self.bootups += 1
            try:
                self.plant_state = NMTState(state)
            except ValueError:
                pass
        elif cid in self._ecu_cobs:
            self._on_ecu_frame(msg)
        elif cid == self._emcy_cob:
            try:
                decoded = self.frames.decode(msg)
            except FrameError:
                return
            if decoded:
                sig = decoded[1]
                code = int(sig["EMCY_ErrorCode"])
                self.emcy.append({
                    "wall_s": round(time.time() - self._t0_wall, 6),
                    "code": code,
                    "name": self.frames.label("EMA_EMCY", "EMCY_ErrorCode", code),
                    "status_word": int(sig["EMCY_StatusWord"]),
                    "cycle": int(sig["EMCY_Cycle"])})


    def _on_rx_error(self, exc: Exception) -> None:
        """A frame that could not be handled (or a failing bus) on the receive thread:
        kept for the main thread to report; the thread goes on."""
        if self.rx_error is None:
            self.rx_error = exc
        time.sleep(0.01)    # a bus that fails at every recv must not spin a core

    def listen(self) -> None:
        """Start the receive thread (SDO, heartbeat, EMCY, log) for set-up and queries."""
        if self._notifier is None:
            mon = _Callback(self._monitor, self._on_rx_error)
            self._notifier = can.Notifier(self.bus, [mon, MessageListener(self.network)],
                                          timeout=0.02)
            if self._listen_t0 is None:
                self._listen_t0 = self._clock()

    def unlisten(self) -> None:
        if self._notifier is not None:
            self._notifier.stop(timeout=1.0)
            self._notifier = None

    def close(self) -> None:
        self.stop_heartbeat()
        self.unlisten()
        if self.log is not None:
            self.log.close()

    # -- NMT and heartbeat ------------------------------------------------------------------
    def nmt(self, command: NMTCommand) -> None:
        self.send(self.frames.encode("NMT", {"NMT_Command": int(command),
                                             "NMT_NodeId": self.node_id}))

    def heartbeat(self, state: NMTState = NMTState.OPERATIONAL, force: bool = False) -> None:
        """The ECU's heartbeat when one is due on the wall clock (every 0.1 s, the DBC's
        cycle time), or at once with `force` (the lockstep SYNC grid)."""
        now = self._clock()
        if force or now >= self._hb_next:
            self.send(self.frames.encode("ECU_Heartbeat", {"ECU_NMTState": int(state)}))
            self._hb_next = now + self._hb_period

    def start_heartbeat(self) -> None:
        """Heartbeat from a thread on the wall clock while the ECU sets the node up (SDO
        waits), so another ECU sees this one and the consumer is never starved."""
        if self._setup_hb is not None:
            return
        done = threading.Event()

        def beat() -> None:
            while not done.is_set():
                try:
                    self.heartbeat()
                except BenchError:
                    return          # the bus is gone: the main thread will say so
                done.wait(self._hb_period / 4)

        th = threading.Thread(target=beat, daemon=True, name="ecu-heartbeat")
        self._setup_hb = (th, done)
        th.start()

    def stop_heartbeat(self) -> None:
        if self._setup_hb is not None:
            th, done = self._setup_hb
            done.set()
            th.join(1.0)
            self._setup_hb = None



class _TeeBus:
    """The bus as canopen's Network sees it: sends are also logged (SDO, NMT)."""

    def __init__(self, bus: can.BusABC, ecu: EcuLink) -> None:
        self._bus, self._ecu = bus, ecu

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._ecu._log_sent(msg)
        self._bus.send(msg, timeout)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._bus, name)


class _Callback(can.Listener):
    """A function as a python-can listener; `on_error` handles what any listener of the
    notifier raised (python-can then keeps its thread running)."""

    def __init__(self, fn: Callable[[can.Message], None],
                 on_error: Callable[[Exception], None] | None = None) -> None:
        self.fn = fn
        self._on_error = on_error

    def on_message_received(self, msg: can.Message) -> None:
        self.fn(msg)

    def on_error(self, exc: Exception) -> None:
        if self._on_error is not None:
            self._on_error(exc)
