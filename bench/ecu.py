"""The ECU: a CANopen master that runs the bench's controller against the plant over the bus.

It holds a python-can bus and nothing of the plant but what the bus carries: NMT, SYNC
production, its own heartbeat, SDO (canopen `RemoteNode` from `ema_contract/dbc/ema.eds`) and the
PDOs of `ema_contract/dbc/ema.dbc` (cantools). The same `bench.control.Controller` as the in-process
harness computes the current demand, so a lockstep bus run reproduces
`bench.harness.simulate` within the DBC quantisation.

Per control period k (CiA 301 synchronous PDOs):

    ECU: SYNC(k) -> plant: latches RPDO(k-1), sends TPDO1-3 (sensors at t_k), steps
    ECU: sends ECU_Setpoint(k) (the set-points of t_k) right after its SYNC
    ECU: decodes TPDOs, demand(k) = controller(set-points(t_k), measurements(t_k)),
         sends RPDO1(k)  -> applied by the plant at SYNC(k+1)

`pace="sync"`: the next SYNC goes out as soon as the period is done (lockstep);
`pace="realtime"`: SYNCs are released on absolute wall-clock deadlines
(`plant_rt.pacing`), and a TPDO that misses its window leaves the previous value.

Every frame goes to the candump log: received frames as they arrive, the ECU's own
as it sends them (with ``echo=True``, as the bus returns them through
``receive_own_messages``, at the cost of one more frame per send to receive). The log is
flushed and closed whatever ends the run.

A run is a success only when nothing spoilt it (issue 9): the plant reporting a
condition that changes what it does with the demand (`FAILING_BITS`, any EMCY outside
`REPORTING_EMCY`), another ECU on the bus (`claim` before anything is sent, any foreign
SYNC/RPDO/set-point/heartbeat during the run), a log that cannot be written, or a
signal (`StopSignal`) end it with an error, the partial trace kept and the node set
PRE-OPERATIONAL. In lockstep the heartbeat follows the SYNC grid (the plant counts its
consumer time in SYNC periods) and the wall clock while waiting.
"""

from __future__ import annotations

import gc
import logging
import math
import signal
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import can
import canopen
import numpy as np
from canopen.network import MessageListener
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench import BenchError
from bench.control import Controller, ControllerParams
from bench.profiles import Profile
from bench.trace import Trace, max_rows, probe_output
from ema_contract.frames import FrameError, Frames, load_od
from ema_contract.states import ControlWord, NMTCommand, NMTState, Pace, StatusWord
from plant_rt.pacing import RealtimePacer
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import ParameterError, PlantParams, check_value, resolve

TWO_PI = 2.0 * math.pi
# canopen logs SDO aborts and timeouts it reports anyway as exceptions; keep stderr clean
logging.getLogger("canopen").setLevel(logging.CRITICAL)
TPDOS = ("EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3")
# CiA 301 SDO abort codes by which a node says it does not have an object
ABSENT_ABORTS = (0x06020000, 0x06090011)   # object / sub-index does not exist
MISSING = object()                         # what `Ecu.read_optional` returns for them
IDENTITY = {"device_type": (0x1000, None), "vendor_id": (0x1018, 1),
            "product_code": (0x1018, 2), "revision": (0x1018, 3), "serial": (0x1018, 4)}
# why a profile's own parameter settings cannot go to a node without the plant's objects
SETTING_HINTS = {
    "load": "the load is the rig's, not the node's: run it unloaded with --load-n 0 and let "
            "the rig apply its load",
    "schedule": "the degradation schedule exists only in the simulated plant",
}


class PlantLost(BenchError):
    """The plant stopped answering (no TPDO, no heartbeat)."""


class BusLost(BenchError):
    """The bus connection itself failed."""


class PlantFault(BenchError):
    """The plant reported a condition that changes its behaviour: the run is not valid."""


class ForeignEcu(BenchError):
    """Another ECU (another SYNC, set-point or heartbeat producer) drives the node."""


class LogWriteError(BenchError):
    """The candump log could not be written (disk full, file too large, ...)."""


class Interrupted(BenchError):
    """The run was stopped by a signal (SIGINT, SIGTERM)."""

    def __init__(self, signum: int, where: str = "") -> None:
        self.signum = int(signum)
        super().__init__(f"interrupted by {signal.Signals(signum).name}{where}")


# Plant conditions that change what the plant does with the ECU's demand (docs/bus.md):
# a run that sees one is not a valid run. Status word bit -> EMCY label (dbc value table).
FAILING_BITS: dict[StatusWord, str] = {
    StatusWord.COMMAND_TIMEOUT: "heartbeat_lost",
    StatusWord.PLANT_FAULT: "plant_fault",
    StatusWord.DEMAND_CLAMPED: "demand_invalid",
}
FAILING_TEXT = {
    "heartbeat_lost": "a command timeout (its heartbeat consumer lost the ECU: demand "
                      "forced to 0)",
    "plant_fault": "a plant fault (non-finite state: the plant stopped integrating)",
    "demand_invalid": "an invalid demand (NaN or beyond its current limit: replaced or "
                      "clamped)",
    "pdo_length": "an RPDO of the wrong length (a demand was not applied)",
}
# EMCYs that only report (the plant does the same with the demand): over-current (the
# drive at its current limit, normal in a step), end of stroke and over-temperature (flags
# only: no end stop, no derating), and the all-clear. Any other code fails the run.
REPORTING_EMCY = ("no_error", "overcurrent", "end_of_stroke", "overtemperature")
# frames only the ECU sends: seen from another producer, another ECU drives the node
ECU_FRAMES = ("SYNC", "EMA_RPDO1", "ECU_Setpoint", "ECU_Heartbeat")


class StopSignal:
    """SIGINT/SIGTERM for a bus run. Outside the control loop a signal raises
    `Interrupted` at once; inside it (`defer` set) it only records `signum`, which the
    loop checks every period, so a signal never cuts a frame, the log or the trace."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.signum: int | None = None
        self.defer = False

    def _handler(self, signum: int, frame: Any) -> None:  # noqa: ARG002
        self.signum = signum
        if not self.defer:
            raise Interrupted(signum)

    @contextmanager
    def installed(self) -> Iterator[StopSignal]:
        """Handle SIGINT and SIGTERM here for the duration of the block."""
        old = {s: signal.signal(s, self._handler) for s in self.SIGNALS}
        try:
            yield self
        finally:
            for s, h in old.items():
                signal.signal(s, h)


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


@dataclass
class NodeInfo:
    """What `Ecu.prepare` found on the node beyond CiA 301 (the trace's ``meta["node"]``)."""
    identity: dict[str, int] = field(default_factory=dict)   # 0x1000, 0x1018 sub 1-4
    missing: list[str] = field(default_factory=list)     # optional objects the node lacks
    params_complete: bool = True       # every 0x2000-0x2008 parameter was read back
    params: dict[str, Any] = field(default_factory=dict)     # those read (node's values)
    encoder_counts_per_rev: int = 0
    encoder_counts_source: str = ""
    sync_period_s: float = 0.0
    sync_period_source: str = ""
    notes: list[str] = field(default_factory=list)       # what the ECU did about it


class _Log(can.Listener):
    """Every frame into a candump log (python-can's CanutilsLogWriter).

    A write that fails (disk full, file too large) is kept in `error` and ends the
    logging, never the thread that delivered the frame: the ECU reports it
    (`raise_error`) at its next check instead of losing its receive thread."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.writer = can.CanutilsLogWriter(self.path)
        self.count = 0
        self.error: Exception | None = None
        self.closed = False
        self._last_flush = time.monotonic()
        self._lock = threading.Lock()     # set-up: notifier thread and main thread

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            if self.error is not None or self.closed:
                return
            try:
                self.writer.on_message_received(msg)
                self.count += 1
                now = time.monotonic()
                if now - self._last_flush > 0.5:
                    self.writer.file.flush()
                    self._last_flush = now
            except (OSError, ValueError) as exc:
                self.error = exc

    def raise_error(self, where: str = "") -> None:
        """LogWriteError if a write has failed (`where`: when, for the message)."""
        exc = self.error
        if exc is not None:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            raise LogWriteError(f"cannot write the log {self.path}: {reason}{where}")

    def close(self) -> None:
        """Flush and close; a failing last flush is kept in `error` like any write."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            try:
                self.writer.stop()
            except (OSError, ValueError) as exc:
                if self.error is None:
                    self.error = exc
                try:
                    self.writer.file.close()
                except (OSError, ValueError):
                    pass
            except Exception:  # noqa: BLE001 - closing must not mask the run's error
                pass


class Ecu:
    """The bench's CANopen master for the actuator node `node_id` on `bus`."""

    def __init__(self, bus: can.BusABC, node_id: int | None = None, ecu_id: int | None = None,
                 log_path: str | Path | None = None, echo: bool = False,
                 sdo_timeout_s: float = 0.5) -> None:
        self.bus = bus
        self.frames = Frames(node_id, ecu_id)
        self.node_id = self.frames.node_id
        self.ecu_id = self.frames.ecu_id
        self.od = load_od(self.node_id)
        self.network = canopen.Network(_TeeBus(bus, self))   # canopen's sends are logged too
        self.remote = canopen.RemoteNode(self.node_id, self.od)
        self.network.add_node(self.remote)
        self.remote.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
        self.param_objects = ParamObjects(self.od)
        self.log = _Log(Path(log_path)) if log_path else None
        self.echo = echo               # the bus returns our own frames (for the log)
        self.emcy: list[dict[str, Any]] = []
        self._emcy_seen = 0        # EMCYs already checked by the run (_check_emcy)
        self.plant_state: NMTState | None = None
        self.plant_hb: float | None = None
        self.bootups = 0
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
        # issue 9: claim on the node, foreign producers, receive errors, abort
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
        """Log an own frame just before it goes out, so that an answer (received on the
        notifier thread) can never precede its request in the log."""
        if not self.echo and self.log is not None:
            msg.timestamp = time.time()
            msg.is_rx = False
            self.log.on_message_received(msg)

    def _monitor(self, msg: can.Message) -> None:
        """Log a received frame and track the plant's heartbeat and EMCY."""
        if self.log is not None:
            self.log.on_message_received(msg)
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
                    "wall_s": round(msg.timestamp - self._t0_wall, 6) if msg.timestamp else None,
                    "code": code,
                    "name": self.frames.label("EMA_EMCY", "EMCY_ErrorCode", code),
                    "status_word": int(sig["EMCY_StatusWord"]),
                    "cycle": int(sig["EMCY_Cycle"])})

    def _on_ecu_frame(self, msg: can.Message) -> None:
        """A frame only an ECU sends: our own echo, or another ECU on the bus."""
        key = (msg.arbitration_id, bytes(msg.data))
        if self.echo and self._own_echo[key] > 0:
            self._own_echo[key] -= 1
        else:
            name = self._ecu_cobs[msg.arbitration_id]
            if name not in self.foreign_seen:
                self.foreign_seen[name] = self._clock()
            if self.foreign is None:
                self.foreign = (name, self._clock())

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

    # -- claim, checks and abort (issue 9) -------------------------------------------------
    def claim(self, announce: Callable[[str], None] | None = None) -> None:
        """Make sure no other ECU drives the node, before this one sends any NMT command
        or SDO write: listen for two heartbeat periods (the plant's and an ECU's); a SYNC,
        RPDO1, set-point or ECU heartbeat from another producer means another ECU is
        there (ForeignEcu). A node left OPERATIONAL with no SYNC (an ECU killed in
        lockstep) is taken over, and `announce` says so."""
        self.listen()
        window = 2 * max(self._hb_period,
                         self.frames.cycle_time_ms("EMA_Heartbeat") / 1000.0)
        end = (self._listen_t0 or self._clock()) + window
        while self.foreign is None and self._clock() < end:
            time.sleep(0.01)
        if self.foreign is not None:     # name the most telling frame: wait for a SYNC
            settle = self._clock() + 0.05
            while "SYNC" not in self.foreign_seen and self._clock() < settle:
                time.sleep(0.005)
        self.check_foreign()
        self.check_receive()
        if self.plant_state == NMTState.OPERATIONAL and announce is not None:
            announce(f"node 0x{self.node_id:02X} is OPERATIONAL with no SYNC on the bus "
                     f"(an ECU stopped without setting it PRE-OPERATIONAL): taking it over")
        self._claimed = True

    def check_foreign(self, where: str = "") -> None:
        if self.foreign is not None:
            seen = dict(self.foreign_seen)
            name = next((n for n in ECU_FRAMES if n in seen), self.foreign[0])
            raise ForeignEcu(f"another ECU is driving node 0x{self.node_id:02X} "
                             f"({name} from another producer{where}); stop it first")

    def check_receive(self, where: str = "") -> None:
        """The log's and the receive thread's failures, as errors of the run."""
        if self.log is not None:
            self.log.raise_error(where)
        if self.rx_error is not None:
            exc = self.rx_error
            raise BusLost(f"receiving from the bus failed{where}: {type(exc).__name__}: "
                          f"{exc}")

    def abort(self) -> None:
        """After a failed or interrupted run, best effort: NMT enter-pre-operational, so
        the node does not stay OPERATIONAL without its ECU. Never raises."""
        self.stop_heartbeat()
        if self._aborted or not (self._claimed or self._started):
            return
        self._aborted = True
        try:
            self.nmt(NMTCommand.ENTER_PRE_OPERATIONAL)
        except Exception:  # noqa: BLE001 - best effort: the bus may be what failed
            pass

    def wait_for_plant(self, timeout: float = 0.5) -> NMTState:
        """The plant's NMT state from its heartbeat, else from an SDO read (the heartbeat
        may be disabled); PlantLost if neither answers within about `timeout` + 0.3 s."""
        self.listen()
        end = self._clock() + timeout
        seen = self.plant_hb
        while self._clock() < end:
            if self.plant_hb is not None and self.plant_hb != seen:
                return self.plant_state or NMTState.PRE_OPERATIONAL
            time.sleep(0.01)
        try:   # heartbeat disabled (0x1017 = 0)? ask by SDO
            if self.has_object("node_status.nmt_state"):
                return NMTState(int(self.sdo_read("node_status.nmt_state")))
            # a node that answers SDO is PRE-OPERATIONAL or OPERATIONAL (CiA 301)
            return self.plant_state or NMTState.PRE_OPERATIONAL
        except Exception:  # noqa: BLE001
            pass
        raise PlantLost(f"no actuator node 0x{self.node_id:02X} answering on the bus "
                        f"(no heartbeat within {timeout:g} s, no SDO answer)")

    def reset_node(self, timeout: float = 3.0) -> None:
        """NMT reset node and wait for the boot-up frame."""
        self.listen()
        before = self.bootups
        self.nmt(NMTCommand.RESET_NODE)
        end = self._clock() + timeout
        while self._clock() < end:
            if self.bootups > before:
                return
            time.sleep(0.005)
        raise PlantLost(f"actuator node 0x{self.node_id:02X} did not boot up within "
                        f"{timeout:g} s of an NMT reset")

    # -- SDO ----------------------------------------------------------------------------------
    def _sdo_var(self, name: str | int | tuple[int, int]):
        """The SDO variable of object `name`: ``group.leaf`` (e.g. ``node_status.cycles``),
        a group name, an index, or (index, sub-index)."""
        if isinstance(name, tuple):
            group, leaf = name
        elif isinstance(name, str) and "." in name:
            group, leaf = name.split(".", 1)
        else:
            group, leaf = name, None
        try:
            var = self.remote.sdo[group]
            return var[leaf] if leaf is not None else var
        except KeyError:
            raise BenchError(f"the object dictionary has no object {name!r}") from None

    @staticmethod
    def _label(var) -> str:
        """``0xIIII sub S (group.leaf)`` of an SDO variable, for messages."""
        od = var.od
        parent = getattr(od, "parent", None)
        if parent is None:
            return f"0x{od.index:04X} ({od.name})"
        return f"0x{od.index:04X} sub {od.subindex} ({parent.name}.{od.name})"

    def _note_absent(self, var, code: int) -> None:
        """Remember that the node lacks `var` (`code` 0x06020000: its whole object)."""
        od = var.od
        if code == ABSENT_ABORTS[0]:
            self._absent_index.add(od.index)
            parent = getattr(od, "parent", None)
            label = f"0x{od.index:04X} ({(parent or od).name})"
        else:
            self._present[(od.index, od.subindex)] = False
            label = self._label(var)
        self._missing.setdefault(label, None)

    @property
    def missing(self) -> list[str]:
        """Optional objects the node was found not to have (labels, sorted)."""
        return sorted(self._missing)

    def has_object(self, name: str | int | tuple[int, int]) -> bool:
        """True if the node has object `name`: an SDO upload is answered, or refused for
        another reason than absence (e.g. a write-only object). Cached per object."""
        self.listen()
        var = self._sdo_var(name)
        od = var.od
        key = (od.index, od.subindex)
        if od.index in self._absent_index:
            return False
        if key not in self._present:
            try:
                self.remote.sdo.upload(*key)
                self._present[key] = True
            except SdoAbortedError as exc:
                if exc.code in ABSENT_ABORTS:
                    self._note_absent(var, exc.code)
                else:
                    self._present[key] = True
            except SdoCommunicationError as exc:
                raise PlantLost(f"no SDO answer reading {self._label(var)}: {exc}") from None
        return self._present.get(key, False)

    def read_optional(self, name: str | int | tuple[int, int]) -> Any:
        """Object `name` by SDO, or `MISSING` if the node does not have it (recorded in
        `missing`); other refusals are a BenchError, no answer PlantLost."""
        self.listen()
        var = self._sdo_var(name)
        if var.od.index in self._absent_index or self._present.get(
                (var.od.index, var.od.subindex)) is False:
            return MISSING
        try:
            value = var.raw
        except SdoAbortedError as exc:
            if exc.code in ABSENT_ABORTS:
                self._note_absent(var, exc.code)
                return MISSING
            raise BenchError(f"the plant refused to read {self._label(var)}: {exc}") from None
        except SdoCommunicationError as exc:
            raise PlantLost(f"no SDO answer reading {self._label(var)}: {exc}") from None
        self._present[(var.od.index, var.od.subindex)] = True
        return value

    def sdo_read(self, name: str | int | tuple[int, int]) -> Any:
        """Read an object by name (``group.leaf``, e.g. ``node_status.cycles``)."""
        value = self.read_optional(name)
        if value is MISSING:
            raise BenchError(f"actuator node 0x{self.node_id:02X} has no object "
                             f"{self._label(self._sdo_var(name))}")
        return value

    def sdo_write(self, name: str | int | tuple[int, int], raw: Any) -> None:
        self.listen()
        var = self._sdo_var(name)
        try:
            var.raw = raw
        except SdoAbortedError as exc:
            if exc.code in ABSENT_ABORTS:
                self._note_absent(var, exc.code)
                raise BenchError(f"actuator node 0x{self.node_id:02X} has no object "
                                 f"{self._label(var)} (writing {raw!r})") from None
            raise BenchError(f"the plant refused {name} = {raw!r}: {exc}") from None
        except SdoCommunicationError as exc:
            raise PlantLost(f"no SDO answer writing {name}: {exc}") from None

    def set_params(self, values: dict[str, Any]) -> None:
        """Write plant parameters by SDO (checked here first for a clear message)."""
        for name, value in values.items():
            try:
                info = resolve(name)
                raw = ParamObjects.to_od(info, check_value(info, value))
            except ParameterError as exc:
                raise BenchError(str(exc)) from None
            self.sdo_write(info.name, raw)

    def check_settable(self, values: dict[str, Any], origin: dict[str, str] | None = None
                       ) -> None:
        """BenchError (one line, naming every setting and object) if the node lacks an
        object that `values` would write; `origin` says where each name came from
        (``--set``, ``profile NAME``), by canonical parameter name."""
        origin = origin or {}
        absent: dict[str, list[str]] = {}
        for name in values:
            try:
                info = resolve(name)
            except ParameterError as exc:
                raise BenchError(str(exc)) from None
            if not self.has_object(info.name):
                absent.setdefault(origin.get(info.name, "the run"), []).append(info.name)
        if not absent:
            return
        parts = []
        for source, names in absent.items():
            objs = ", ".join(f"0x{self.param_objects.by_name[n].index:04X} sub "
                             f"{self.param_objects.by_name[n].subindex}" for n in names)
            part = f"{', '.join(names)} ({source}) need{'s' if len(names) == 1 else ''} {objs}"
            hints = {SETTING_HINTS[n.split('.')[0]] for n in names
                     if n.split(".")[0] in SETTING_HINTS}
            parts.append(part + "".join(f": {h}" for h in sorted(hints)))
        raise BenchError(f"actuator node 0x{self.node_id:02X} lacks the parameter objects "
                         "this run writes: " + "; ".join(parts))

    def read_params(self) -> PlantParams:
        """Every plant parameter the node has, read by SDO (the others at their default;
        `node_info.params_complete` says whether all were there)."""
        values = {}
        for name, po in self.param_objects.by_name.items():
            raw = self.read_optional(name)
            if raw is not MISSING:
                values[name] = ParamObjects.from_od(po.info, raw)
        self.node_info.params = values
        self.node_info.params_complete = len(values) == len(self.param_objects.by_name)
        return PlantParams().with_dict(values)

    def read_status(self) -> dict[str, Any]:
        """Object 0x2100 (node status and counters) by name; {} if the node has none."""
        rec = self.od["node_status"]
        if not self.has_object("node_status.nmt_state"):
            return {}
        return {var.name: self.sdo_read(f"node_status.{var.name}")
                for sub, var in rec.subindices.items() if sub}

    def read_identity(self) -> dict[str, int]:
        """CiA 301 device type (0x1000) and identity (0x1018 sub 1-4), those the node has."""
        out = {}
        for key, (index, sub) in IDENTITY.items():
            v = self.read_optional(index if sub is None else (index, sub))
            if v is not MISSING:
                out[key] = int(v)
        return out

    # -- running a profile ------------------------------------------------------------------
    def prepare(self, pace: Pace, values: dict[str, Any], spin_us: int | None = None,
                origin: dict[str, str] | None = None, encoder_counts: int | None = None,
                sync_driven: bool = False) -> PlantParams:
        """Reset the node, set pace (and the plant pacer's spin window) and parameters,
        restart the plant at t = 0; returns the parameters the plant now has (read back).

        Only NMT, heartbeat, SDO of CiA 301 objects and the DBC's PDOs are required; the
        optional objects (0x2000-0x2008, 0x2100, 0x2200) are used when the node has them.
        Without them: `node_info` lists what is missing and `node_info.notes` what the
        ECU does instead (docs/node-contract.md). `encoder_counts` (counts/rev) stands in
        for a missing 0x2003 sub 11; `sync_driven` vouches that a node without 0x2200
        steps exactly one period per SYNC (else `Pace.SYNC` is refused)."""
        self.wait_for_plant(2.0)
        self.reset_node()
        info = self.node_info = NodeInfo(notes=[])
        info.identity = self.read_identity()
        self._set_pace(pace, sync_driven)
        if spin_us is not None and self.has_object("node_control.spin_us"):
            self.sdo_write("node_control.spin_us", int(spin_us))
        self.check_settable(values, origin)
        self.set_params(values)
        if self.has_object("node_control.reset_plant"):
            self.sdo_write("node_control.reset_plant", 1)
        else:
            info.notes.append("node has no plant reset (0x2200 sub 2 missing): the run "
                              "starts from the node's state after NMT reset node")
        params = self._timing(self.read_params(), encoder_counts)
        if not info.params_complete:
            absent = sorted({po.index for n, po in self.param_objects.by_name.items()
                             if n not in info.params})
            span = (f"0x{absent[0]:04X}-0x{absent[-1]:04X}" if len(absent) > 1
                    and absent[-1] - absent[0] == len(absent) - 1 else
                    ", ".join(f"0x{i:04X}" for i in absent))
            info.notes.append(f"node has {'no' if not info.params else 'not all'} plant "
                              f"parameter objects ({span} missing): {len(info.params)} of "
                              f"{len(self.param_objects.by_name)} read back")
        if not self.has_object("node_status.nmt_state"):
            info.notes.append("node has no counters (0x2100 missing): plant counters "
                              "skipped")
        info.missing = self.missing
        return params

    def _set_pace(self, pace: Pace, sync_driven: bool) -> None:
        """Write the lockstep object 0x2200 sub 1, or decide without it."""
        if self.has_object("node_control.pace"):
            self.sdo_write("node_control.pace", int(pace))
        elif pace == Pace.SYNC and not sync_driven:
            raise BenchError(f"--pace sync needs the lockstep object 0x2200 sub 1, which "
                             f"actuator node 0x{self.node_id:02X} does not have (a real "
                             "actuator runs on its own clock): use --pace realtime")
        elif pace == Pace.SYNC:
            self.node_info.notes.append("node has no lockstep (0x2200 sub 1 missing): "
                                        "lockstep on the caller's word that the node "
                                        "steps one period per SYNC")
        else:
            self.node_info.notes.append("node has no lockstep (0x2200 sub 1 missing): "
                                        "running in real time")

    def _timing(self, params: PlantParams, encoder_counts: int | None) -> PlantParams:
        """`params` with the encoder resolution and SYNC period the run uses: the node's
        parameter objects, else `encoder_counts` / object 0x1006, else the EDS defaults."""
        info = self.node_info
        cpr_name, ts_name = "sensors.encoder_counts_per_rev", "sim.sync_period_s"
        cpr_po = self.param_objects.by_name[cpr_name]
        cpr_obj = f"0x{cpr_po.index:04X} sub {cpr_po.subindex}"
        cpr_default = int(self.od[cpr_po.index][cpr_po.subindex].default)
        if cpr_name in info.params:
            cpr, source = int(info.params[cpr_name]), f"node {cpr_obj}"
            if encoder_counts is not None and int(encoder_counts) != cpr:
                raise BenchError(f"--encoder-counts {encoder_counts} disagrees with the node's "
                                 f"encoder resolution {cpr_obj} = {cpr} counts/rev")
        elif encoder_counts is not None:
            cpr, source = int(encoder_counts), "--encoder-counts"
        else:
            cpr, source = cpr_default, f"the EDS default of {cpr_obj}"
        if cpr_name not in info.params:
            note = (f"node has no encoder resolution ({cpr_obj} missing): {cpr} counts/rev "
                    f"from {source}")
            if encoder_counts is None:
                note += " (--encoder-counts N for another encoder)"
            if cpr != cpr_default:   # decoders assume the default when the log lacks it
                note += f"; the log does not carry it: decode with --counts-per-rev {cpr}"
            info.notes.append(note)
        if ts_name in info.params:
            ts, ts_source = float(info.params[ts_name]), "node 0x2008 sub 1"
        else:
            us = self.read_optional(0x1006)
            if us is not MISSING and int(us) > 0:
                ts, ts_source = int(us) * 1e-6, "node 0x1006"
            else:
                ts = int(self.od[0x1006].default) * 1e-6
                ts_source = "EDS default of 0x1006"
                info.notes.append(f"node has no SYNC period (0x1006 missing or 0): "
                                  f"{ts * 1e3:g} ms, the EDS default")
        info.encoder_counts_per_rev, info.encoder_counts_source = cpr, source
        info.sync_period_s, info.sync_period_source = ts, ts_source
        try:
            return params.with_dict({cpr_name: cpr, ts_name: ts})
        except ParameterError as exc:
            raise BenchError(str(exc)) from None

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
        # in lockstep the clear shows at SYNC 1; in real time the RPDO and the TPDOs cross
        # the bus on their own clocks (a TPDO set may miss its window for a few periods on
        # a loaded machine), so the pre-run latch is tolerated for 20 ms
        grace = 1 if pacer is None else max(1, round(0.02 / ts))
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
                if word & fail_bits and (k >= grace or word & fail_bits != timeout_bit):
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


class _TeeBus:
    """The bus as canopen's Network sees it: sends are also logged (SDO, NMT)."""

    def __init__(self, bus: can.BusABC, ecu: Ecu) -> None:
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


def _at(k: int, ts: float) -> str:
    return f" at t = {k * ts:.3f} s (SYNC {k})"


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


def status_names(word: int) -> list[str]:
    return [f.name.lower() for f in StatusWord if f and f.name and int(word) & f]


__all__ = ["Ecu", "EcuStats", "NodeInfo", "PlantLost", "BusLost", "PlantFault", "ForeignEcu",
           "LogWriteError", "Interrupted", "StopSignal", "run_periods", "status_names"]


def plant_values(profile: Profile, assignments: list[str] | None = None,
                 values: dict[str, Any] | None = None) -> dict[str, Any]:
    """Parameter settings for a run: the profile's own (e.g. the RUL schedule), then
    `values`, then ``NAME=VALUE`` assignments; checked here (BenchError if invalid)."""
    out: dict[str, Any] = dict(profile.params_overrides)
    out.update(values or {})
    for a in assignments or []:
        if "=" not in a:
            raise BenchError(f"--set expects NAME=VALUE, got {a!r}")
        k, v = a.split("=", 1)
        out[k.strip()] = v.strip()
    try:
        PlantParams().with_dict(out)
    except ParameterError as exc:
        raise BenchError(str(exc)) from None
    return out


def setting_origins(profile: Profile, assignments: list[str] | None = None,
                    values: dict[str, Any] | None = None) -> dict[str, str]:
    """Canonical parameter name -> where the run's setting of it comes from (for
    messages): ``profile NAME``, ``values`` or ``--set`` (the last one wins, as in
    `plant_values`)."""
    out: dict[str, str] = {}
    items = [(k, f"profile {profile.name}") for k in profile.params_overrides]
    items += [(k, "values") for k in (values or {})]
    items += [(a.split("=", 1)[0].strip(), "--set") for a in assignments or [] if "=" in a]
    for name, source in items:
        try:
            out[resolve(name).name] = source
        except ParameterError:
            pass
    return out


def _with_node(trace: Trace | None, info: NodeInfo) -> Trace | None:
    """`trace` with what the ECU found on the node (``meta["node"]``); the parameters in
    ``meta["params"]`` only when the node gave them all."""
    if trace is not None:
        node = asdict(info)
        if info.params_complete:
            del node["params"]           # all of them are in meta["params"]
        else:
            trace.meta.pop("params", None)
        trace.meta["node"] = node
    return trace


def run_over_bus(profile: Profile, values: dict[str, Any] | None = None,
                 assignments: list[str] | None = None, pace: Pace | str = Pace.SYNC,
                 duration_s: float | None = None, log_path: str | Path | None = None,
                 progress: bool = False, settings: dict[str, Any] | None = None,
                 start_plant: bool = True, cparams: ControllerParams | None = None,
                 node_id: int | None = None, announce: Callable[[str], None] | None = None,
                 echo: bool = False, spin_us: int = 200, encoder_counts: int | None = None,
                 sync_driven: bool = False, stop: StopSignal | None = None) -> Trace:
    """Run `profile` against the plant over the bus and return the trace.

    The bus is the configured one (flags in `settings`, environment, config file,
    vcan0, the hub of `bench up`), else a private loopback hub started for this run.
    When no plant answers on a simulated bus (hub, virtual, vcan) and `start_plant`,
    a plant process is started for the run. Everything started here is stopped here.

    A node without the simulated plant's optional objects (a real actuator,
    docs/node-contract.md) is run with what it has: `announce` is told what is missing
    and what the ECU does instead, and ``trace.meta["node"]`` records it (`NodeInfo`);
    ``meta["params"]`` is then left out, since the ECU does not know the node's
    parameters. `encoder_counts` (counts/rev) stands in for a missing encoder
    resolution object; `sync_driven` vouches that a node without the lockstep object
    steps one period per SYNC, so that `pace` "sync" may run against it.

    Before anything starts: the run's length (`run_periods`) and the log path are
    checked. Before any NMT command or SDO write: `Ecu.claim` (no other ECU on the node).
    On error the partial trace is in the exception's ``trace`` attribute, the log is
    closed and the node, once claimed, is set PRE-OPERATIONAL (`Ecu.abort`)."""
    from bench.bus import close_bus, connect, is_simulated, session
    from bench.bus.procs import start_plant as _start_plant

    pace = Pace[pace.upper()] if isinstance(pace, str) else Pace(pace)
    vals = plant_values(profile, assignments, values)
    origin = setting_origins(profile, assignments, values)
    if encoder_counts is not None:
        try:
            check_value(resolve("sensors.encoder_counts_per_rev"), encoder_counts)
        except ParameterError as exc:
            raise BenchError(f"--encoder-counts: {exc}") from None
    run_periods(profile.duration_s if duration_s is None else duration_s,
                PlantParams().with_dict(vals).sim.sync_period_s)
    if log_path:
        probe_output(log_path, "log")
    say = announce or (lambda s: None)
    with session(settings) as sess:
        bus = connect(sess.cfg, receive_own_messages=echo)
        ecu = None
        try:
            ecu = Ecu(bus, node_id=node_id, log_path=log_path, echo=echo)
            try:
                ecu.wait_for_plant(1.0 if sess.children else 0.6)
            except PlantLost:
                ecu.check_receive()
                if not (start_plant and is_simulated(sess.cfg)):
                    raise PlantLost(f"no actuator node 0x{ecu.node_id:02X} answering on "
                                    f"{sess.description}") from None
                say("starting a plant for this run")
                sess.children.append(_start_plant(sess.cfg, pace=pace.name.lower(),
                                                  node_id=node_id))
            say(f"bus {sess.description}")
            ecu.claim(say)
            ecu.start_heartbeat()
            params = ecu.prepare(pace, vals, spin_us if pace == Pace.REALTIME else None,
                                 origin=origin, encoder_counts=encoder_counts,
                                 sync_driven=sync_driven)
            for note in ecu.node_info.notes:
                say(note)
            ecu.check_foreign(" during set-up")
            ecu.check_receive(" during set-up")
            trace = ecu.run(profile, params, cparams, pace, duration_s, progress,
                            spin_us=spin_us, stop=stop)
            if ecu.log is not None:     # the last frames reach the disk, or the run fails
                ecu.log.close()
                ecu.log.raise_error(" at the end of the run")
            _with_node(trace, ecu.node_info)
            trace.meta["bus"] = sess.description
            if log_path:
                trace.meta["log"] = str(log_path)
            return trace
        except BaseException as exc:
            if ecu is not None:
                ecu.abort()
                if isinstance(exc, (BenchError, KeyboardInterrupt)):
                    exc.trace = _with_node(ecu.partial, ecu.node_info)  # type: ignore[attr-defined]
            raise
        finally:
            if ecu is not None:
                ecu.close()
            close_bus(bus)
