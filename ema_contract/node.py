"""The CANopen node (CiA 301) every actuator on the bench's bus is built on: `CanopenNode`.

One thread does everything (receive, SDO, PDOs, timers): no lock, no receive thread, and
a lockstep run is deterministic. What the base does, for every node:

- the object dictionary and its SDO server (expedited and segmented transfers):
  canopen's `LocalNode`, fed frame by frame through `Network.notify` (no notifier
  thread), with the node's hooks `sdo_read` / `sdo_write` in front of the store;
- the NMT slave (CiA 301): boot-up, PRE-OPERATIONAL, OPERATIONAL, STOPPED, reset node
  and reset communication, states as `ema_contract.states.NMTState` (canopen's
  `NmtSlave`, string states and a heartbeat from a timer thread, is unhooked: a node
  whose loop stalls must stop its heartbeat);
- the heartbeat producer (0x1017) and the reception of the ECU's heartbeat (the
  producer named by 0x1016 sub 1, its time in `ecu_hb`); what a lost heartbeat does is
  the node's (`on_timers`);
- SYNC dispatch: a SYNC of 0 or 1 byte goes to `on_sync`, any other is a bad frame;
- frame dispatch by COB id (`on_frame` adds one, e.g. RPDO1): a bad frame is counted
  (`counters`), handed to `on_bad_frame` and never raised;
- the loop: `serve()` (poll the bus, run the timers, `serve_once` per turn) and
  `drain()` (the frames already received and the timers, without waiting: a node
  behind its releases must still read frames and send its heartbeat).

Frame layouts come from the DBC (`ema_contract.frames.Frames`), the objects from the
EDS (`ema_contract.frames.load_od`, `cia301_od` for a node with only the CiA 301 ones).
The nodes built on it: `plant_rt.node.PlantNode` (the simulated plant),
`indie_plant.node.IndieNode` (the independent actuator) and the test double
`tests/integration/minimal_node.py` (a vendor's minimal actuator).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, cast

import can
import canopen
from canopen.objectdictionary import ObjectDictionary

from ema_contract.frames import FrameError, Frames, load_od
from ema_contract.states import NMTCommand, NMTState

log = logging.getLogger("ema_contract.node")

# SDO abort codes (CiA 301)
ABORT_READ_ONLY = 0x06010002
ABORT_VALUE_RANGE = 0x06090030
ABORT_VALUE_HIGH = 0x06090031
ABORT_VALUE_LOW = 0x06090032
ABORT_APP_REFUSED = 0x08000020
ABORT_DEVICE_STATE = 0x08000022
# error register bits (CiA 301 0x1001)
ERR_GENERIC, ERR_CURRENT, ERR_TEMPERATURE, ERR_COMMUNICATION, ERR_MANUFACTURER = (
    0x01, 0x02, 0x08, 0x10, 0x80)
TPDOS = ("EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3")
COMMUNICATION_END = 0x2000     # objects below: the communication profile area (CiA 301)
IDLE_POLL_S = 0.05             # longest wait for a frame when no timer is due sooner


def cia301_od(node_id: int, keep: Iterable[int] = (), identity: bool = True
              ) -> ObjectDictionary:
    """The EDS's object dictionary with only the CiA 301 objects (0x1000-0x1FFF) and the
    indices in `keep`; without the identity object 0x1018 too unless `identity`."""
    od = load_od(node_id)
    kept = set(keep)
    for index in [i for i in od.keys() if isinstance(i, int) and i not in kept
                  and (i >= COMMUNICATION_END or i == 0x1018 and not identity)]:
        del od[index]
    return od


@dataclass
class FrameCounters:
    """Frames received, and of them those not processed (reset by an NMT reset)."""
    frames_received: int = 0
    bad_frames: int = 0          # a known id that did not decode or could not be handled
    unknown_frames: int = 0      # error, remote, extended or an id not in the DBC

    def reset(self) -> None:
        for k in self.__dataclass_fields__:
            setattr(self, k, 0)


Handler = Callable[[can.Message], None]


class CanopenNode:
    """A CiA 301 node on `bus` with the objects `od` and the frames `frames` (module
    docstring). Subclasses fill the hooks: `on_sync`, `sdo_read` / `sdo_write`,
    `on_reset_node`, `on_reset_communication`, `on_timers`, `on_bad_frame`, `serve_once`
    and frames of their own through `on_frame`."""

    logger = log

    def __init__(self, bus: can.BusABC, frames: Frames, od: ObjectDictionary,
                 clock: Callable[[], float] = time.monotonic,
                 counters: FrameCounters | None = None) -> None:
        self.bus = bus
        self.frames = frames
        self.node_id = frames.node_id
        self.od: Any = cast(Any, od)            # canopen ObjectDictionary (untyped items)
        self.local = canopen.LocalNode(self.node_id, od)
        self.network = canopen.Network(bus)     # no notifier: frames are fed by handle()
        self.network.add_node(self.local)
        self.network.unsubscribe(0, self.local.nmt.on_command)
        if self.local.nmt.on_write in self.local._write_callbacks:
            self.local._write_callbacks.remove(self.local.nmt.on_write)
        self.local.add_read_callback(self._sdo_read)
        self.local.add_write_callback(self._sdo_write)
        self.clock = clock
        self.counters: Any = FrameCounters() if counters is None else counters
        self.state = NMTState.BOOT_UP
        self.running = False
        self.heartbeat_ms = int(self.od[0x1017].default)      # producer time (0x1017)
        self.consumer = int(self.od[0x1016][1].default)       # 0x1016 sub 1: id << 16 | ms
        self.next_hb = 0.0                               # wall clock of the next heartbeat
        self.ecu_hb: float | None = None                 # wall clock of the ECU's last one
        self.sdo_cob = frames.sdo_rx
        self._rx_ids: dict[int, Handler] = {
            frames.cob["NMT"]: self._on_nmt, frames.cob["SYNC"]: self._on_sync_frame,
            self.sdo_cob: self._on_sdo}
        self._known_ids = set(frames.by_cob)

    # -- hooks ------------------------------------------------------------------------------
    def on_sync(self, msg: can.Message) -> None:
        """A SYNC (0 or 1 byte) was received."""

    def on_reset_node(self) -> None:
        """NMT reset node: the application back to its power-on state (before the reset
        of the communication)."""

    def on_reset_communication(self) -> None:
        """NMT reset communication (also after reset node): the node's own communication
        state, before the boot-up frame."""

    def on_timers(self, now: float, nxt: float) -> float:
        """The node's own timers at wall time `now`; `nxt` or the seconds to the next."""
        return nxt

    def on_bad_frame(self, msg: can.Message, exc: FrameError) -> None:
        """A frame of a known id that did not decode (already counted)."""
        self.note(logging.DEBUG, "bad frame ignored: %s", exc)

    def sdo_read(self, index: int, subindex: int, od) -> object | None:  # noqa: ARG002
        """An SDO upload: the value, or None for the object dictionary's store."""
        return None

    def sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:  # noqa: ARG002
        """An SDO download (raise canopen's SdoAbortedError to refuse it)."""

    def serve_once(self) -> None:
        """One turn of `serve()`'s loop: wait for a frame or a timer."""
        self.poll(IDLE_POLL_S)

    def note(self, level: int, fmt: str, *args: object, exc_info: bool = False) -> None:
        """A log line of the node's."""
        self.logger.log(level, fmt, *args, exc_info=exc_info)

    # -- frames -----------------------------------------------------------------------------
    def on_frame(self, cob_id: int, handler: Handler) -> None:
        """Hand the frames of `cob_id` to `handler` (a FrameError it raises: a bad frame)."""
        self._rx_ids[cob_id] = handler

    def send(self, msg: can.Message) -> None:
        try:
            self.bus.send(msg)
        except can.CanError as exc:
            self.note(logging.WARNING, "send failed: %s", exc)
        except OSError as exc:
            raise ConnectionError(f"bus connection lost: {exc}") from exc

    def handle(self, msg: can.Message) -> None:
        """Process one received frame; bad frames are counted and ignored, never raised."""
        c = self.counters
        c.frames_received += 1
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            c.unknown_frames += 1
            return
        handler = self._rx_ids.get(msg.arbitration_id)
        if handler is None:
            if msg.arbitration_id == 0x700 + (self.consumer >> 16 & 0x7F):
                self.on_ecu_heartbeat(msg)
            elif msg.arbitration_id not in self._known_ids:
                c.unknown_frames += 1
            return
        try:
            handler(msg)
        except FrameError as exc:
            c.bad_frames += 1
            self.on_bad_frame(msg, exc)
        except Exception:  # noqa: BLE001 - a frame must never stop the node
            c.bad_frames += 1
            self.note(logging.ERROR, "frame 0x%03X not processed", msg.arbitration_id,
                      exc_info=True)

    def _on_sync_frame(self, msg: can.Message) -> None:
        if len(msg.data) not in (0, 1):
            raise FrameError(f"SYNC with {len(msg.data)} bytes")
        self.on_sync(msg)

    def _on_sdo(self, msg: can.Message) -> None:
        if self.state == NMTState.STOPPED:
            return
        if len(msg.data) != 8:
            raise FrameError(f"SDO request with {len(msg.data)} bytes")
        self.network.notify(msg.arbitration_id, msg.data, msg.timestamp)

    def on_ecu_heartbeat(self, msg: can.Message) -> None:
        """The heartbeat of the producer 0x1016 sub 1 names."""
        if len(msg.data) != 1:
            self.counters.bad_frames += 1
            return
        self.ecu_hb = self.clock()

    def pdo_frames(self, values: dict[str, float | int], names: Iterable[str] = TPDOS
                   ) -> list[can.Message]:
        """The PDOs `names` with the signal `values`, each clamped to its DBC range."""
        f = self.frames
        return [f.encode(name, {s.name: f.clamp(name, s.name, values[s.name])
                                for s in f.by_name[name].signals}) for name in names]

    def emcy_values(self, label: str, register: int, status_word: int = 0, cycle: int = 0
                    ) -> dict[str, int]:
        """The signals of an EMCY frame for the DBC value-table `label`."""
        return {"EMCY_ErrorCode": self.frames.choice("EMA_EMCY", "EMCY_ErrorCode", label),
                "EMCY_ErrorRegister": register, "EMCY_StatusWord": status_word,
                "EMCY_Cycle": cycle}

    # -- NMT --------------------------------------------------------------------------------
    def boot(self) -> None:
        """Power-on / reset: the boot-up frame, then PRE-OPERATIONAL with the heartbeat."""
        self.state = NMTState.BOOT_UP
        self.send(self.frames.encode("EMA_Heartbeat", {"EMA_NMTState": int(NMTState.BOOT_UP)}))
        self.state = NMTState.PRE_OPERATIONAL
        self.next_hb = self.clock() + self.heartbeat_ms / 1000.0

    def set_state(self, new: NMTState) -> None:
        """An NMT state transition (START, STOP, ENTER PRE-OPERATIONAL, error behaviour)."""
        self.state = new

    def reset_node(self) -> None:
        """NMT reset node: every object back to its EDS default, then reset communication."""
        self.local.data_store.clear()
        self.on_reset_node()
        self.reset_communication()

    def reset_communication(self) -> None:
        """NMT reset communication: the communication objects back to their EDS defaults,
        the node's communication state (`on_reset_communication`), then the boot-up."""
        self.on_reset_communication()
        store = self.local.data_store
        for idx in [i for i in store if i < COMMUNICATION_END]:
            del store[idx]
        self.heartbeat_ms = int(self.od[0x1017].default)
        self.consumer = int(self.od[0x1016][1].default)
        self.ecu_hb = None
        self.boot()

    def _on_nmt(self, msg: can.Message) -> None:
        _, sig = self.frames.decode(msg)  # type: ignore[misc]
        if sig["NMT_NodeId"] not in (0, self.node_id):
            return
        try:
            cmd = NMTCommand(sig["NMT_Command"])
        except ValueError:
            self.counters.bad_frames += 1
            return
        if cmd == NMTCommand.RESET_NODE:
            self.reset_node()
        elif cmd == NMTCommand.RESET_COMMUNICATION:
            self.reset_communication()
        elif cmd == NMTCommand.START:
            self.set_state(NMTState.OPERATIONAL)
        elif cmd == NMTCommand.STOP:
            self.set_state(NMTState.STOPPED)
        elif cmd == NMTCommand.ENTER_PRE_OPERATIONAL:
            self.set_state(NMTState.PRE_OPERATIONAL)

    # -- SDO --------------------------------------------------------------------------------
    def _sdo_read(self, index: int, subindex: int, od) -> object | None:
        if index == 0x1017:
            return self.heartbeat_ms
        if index == 0x1016 and subindex == 1:
            return self.consumer
        return self.sdo_read(index, subindex, od)

    def _sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:
        if index == 0x1017:
            self.heartbeat_ms = int(od.decode_raw(data))
            self.next_hb = self.clock() + self.heartbeat_ms / 1000.0
        elif index == 0x1016 and subindex == 1:
            self.consumer = int(od.decode_raw(data))
        else:
            self.sdo_write(index, subindex, od, data)

    def consumer_timeout_s(self) -> float:
        """The ECU heartbeat's consumer time (0x1016 sub 1, s; 0: not watched)."""
        return (self.consumer & 0xFFFF) / 1000.0

    # -- timers and loop --------------------------------------------------------------------
    def timers(self) -> float:
        """The heartbeat producer and the node's own timers (`on_timers`); returns the
        seconds to the next timer."""
        now = self.clock()
        nxt = IDLE_POLL_S
        if self.heartbeat_ms > 0:
            if now >= self.next_hb:
                self.send(self.frames.encode("EMA_Heartbeat",
                                             {"EMA_NMTState": int(self.state)}))
                self.next_hb += self.heartbeat_ms / 1000.0
                if self.next_hb < now:          # behind: one heartbeat, not a burst
                    self.next_hb = now + self.heartbeat_ms / 1000.0
            nxt = min(nxt, self.next_hb - now)
        return max(self.on_timers(now, nxt), 0.0)

    def _recv(self, timeout: float) -> can.Message | None:
        try:
            return self.bus.recv(timeout=timeout)
        except Exception as exc:  # noqa: BLE001 - CanError, OSError, closed websocket
            raise ConnectionError(f"bus connection lost: {type(exc).__name__}: {exc}") from exc

    def poll(self, timeout: float) -> None:
        """Wait up to `timeout` (or the next timer) for one frame and handle it."""
        msg = self._recv(max(0.0, min(timeout, self.timers())))
        if msg is not None:
            self.handle(msg)

    def drain(self, limit: int = 64) -> None:
        """Serve the timers and the frames already received, without waiting. A node
        behind its releases (a loaded machine: each step ended after the next release)
        never waits, so it read no frame and sent no heartbeat until it caught up: the
        ECU's heartbeat went unseen for 300 ms (a command timeout) and its own for
        0.35 s, which ended the run ("the plant stopped answering at ... SYNC 250")."""
        self.timers()
        for _ in range(limit):
            msg = self._recv(0.0)
            if msg is None:
                return
            self.handle(msg)

    def serve(self, duration_s: float | None = None,
              alive: Callable[[], bool] | None = None) -> None:
        """Boot, then serve the bus until `stop()`, for `duration_s` of wall time, or until
        `alive()` (checked every 0.25 s) returns False."""
        self.running = True
        end = None if duration_s is None else self.clock() + duration_s
        next_check = self.clock() + 0.25
        self.boot()
        while self.running:
            now = self.clock()
            if end is not None and now >= end:
                break
            if alive is not None and now >= next_check:
                next_check = now + 0.25
                if not alive():
                    self.logger.warning("parent process gone: stopping")   # once: loop ends
                    break
            self.serve_once()

    def stop(self) -> None:
        self.running = False


__all__ = ["ABORT_APP_REFUSED", "ABORT_DEVICE_STATE", "ABORT_READ_ONLY", "ABORT_VALUE_HIGH",
           "ABORT_VALUE_LOW", "ABORT_VALUE_RANGE", "CanopenNode", "ERR_COMMUNICATION",
           "ERR_CURRENT", "ERR_GENERIC", "ERR_MANUFACTURER", "ERR_TEMPERATURE",
           "FrameCounters", "TPDOS", "cia301_od"]
