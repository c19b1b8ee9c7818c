"""The independent actuator as a CANopen node that knows only `ema_contract`.

CiA 301 through canopen's `LocalNode` over the EDS's CiA 301 objects (0x1000-0x1FFF)
plus one vendor object, 0x2200 sub 1-2 (pace, restart the physics), so `bench run
--pace sync` can run it in lockstep: NMT slave and boot-up, heartbeat producer (0x1017)
and consumer (0x1016 sub 1), SDO server, RPDO1 in, TPDO1-3 and EMCY out, every frame
encoded from the DBC. No plant parameter objects (0x2000-0x2008, 0x2100): an SDO access
to them is refused with CiA 301's "object does not exist" (0x06020000), as a real drive
does, so the bench can set nothing inside it: the actuator's parameters and its rig load
are this process's flags (the vendor's hardware), not the bus's.

SYNC-driven (CiA 301 synchronous PDOs): at SYNC k in OPERATIONAL it latches the RPDO
received since SYNC k-1, sends TPDO1-3 sampled now, then advances one period holding
that demand (`indie_plant.generate.Actuator`). The rig's axial load (a sine, flags
`--load-n`, `--load-hz`) starts with the physics at t = 0; the load cell reports it.
The node's own cascade is not used on the bus: the ECU closes the loops (node-contract).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import can
import canopen
from canopen.objectdictionary import ObjectDictionary
from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.frames import Frames, load_od
from ema_contract.states import ControlWord, NMTCommand, NMTState
from indie_plant.generate import Actuator

ABORT_VALUE_RANGE = 0x06090030
ABORT_READ_ONLY = 0x06010002
STATUS_COMMAND_TIMEOUT, STATUS_DEMAND_CLAMPED, STATUS_ENABLED = 0x10, 0x20, 0x40
ERR_GENERIC, ERR_COMMUNICATION = 0x01, 0x10
TPDOS = ("EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3")
WINDING_K = 293.15          # no thermal model: the winding sensor reads 20 C


def node_od(node_id: int) -> ObjectDictionary:
    """The EDS's CiA 301 objects and 0x2200 (node control); nothing else from 0x2000 on."""
    od = load_od(node_id)
    for index in [i for i in od.keys() if isinstance(i, int) and i >= 0x2000 and i != 0x2200]:
        del od[index]
    return od


class IndieNode:
    """The node's bus side (single-threaded: `serve()` reads the bus, hands each frame to
    canopen's `Network.notify` and runs the heartbeat timers)."""

    def __init__(self, bus: can.BusABC, actuator: Actuator, node_id: int | None = None,
                 load_n: float = 0.0, load_hz: float = 0.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.bus = bus
        self.act = actuator
        self.load_n, self.load_hz = load_n, load_hz
        self.frames = Frames(node_id, None)
        self.node_id = self.frames.node_id
        self.od = node_od(self.node_id)
        self.local = canopen.LocalNode(self.node_id, self.od)
        self.network = canopen.Network(bus)
        self.network.add_node(self.local)
        self.network.unsubscribe(0, self.local.nmt.on_command)
        self.local._write_callbacks.remove(self.local.nmt.on_write)
        self.local.add_read_callback(self._on_sdo_read)
        self.local.add_write_callback(self._on_sdo_write)
        cob = self.frames.cob
        self.network.subscribe(cob["NMT"], self._on_nmt)
        self.network.subscribe(cob["SYNC"], self._on_sync)
        self.network.subscribe(cob["EMA_RPDO1"], self._on_rpdo)
        self.clock = clock
        self.state = NMTState.BOOT_UP
        self.running = False
        self.bad_frames = 0
        self.pace = 0
        self._reset_communication()

    def _reset_communication(self) -> None:
        self.local.data_store.clear()
        od: Any = self.od
        self.heartbeat_ms = int(od[0x1017].default)
        self.consumer = int(od[0x1016][1].default)
        self.pending = (0.0, 0, False)
        self.ecu_hb: float | None = None
        self.timed_out = False
        self.next_hb = 0.0

    def boot(self) -> None:
        self.send(self.frames.encode("EMA_Heartbeat", {"EMA_NMTState": 0}))
        self.state = NMTState.PRE_OPERATIONAL
        self.next_hb = self.clock() + self.heartbeat_ms / 1000.0

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:  # noqa: ARG002
        if len(data) != 2 or data[1] not in (0, self.node_id):
            return
        cmd = data[0]
        if cmd == NMTCommand.RESET_NODE:
            self.act.reset()
            self.pace = 0
        if cmd in (NMTCommand.RESET_NODE, NMTCommand.RESET_COMMUNICATION):
            self._reset_communication()
            self.boot()
        elif cmd == NMTCommand.START:
            if self.state != NMTState.OPERATIONAL:
                self.pending = (0.0, 0, False)
            self.state = NMTState.OPERATIONAL
        elif cmd == NMTCommand.STOP:
            self.state = NMTState.STOPPED
        elif cmd == NMTCommand.ENTER_PRE_OPERATIONAL:
            self.state = NMTState.PRE_OPERATIONAL

    def timers(self) -> float:
        """Heartbeat producer and consumer; seconds to the next timer."""
        now = self.clock()
        nxt = 0.05
        if self.heartbeat_ms > 0:
            if now >= self.next_hb:
                self.send(self.frames.encode("EMA_Heartbeat", {"EMA_NMTState": int(self.state)}))
                self.next_hb = max(self.next_hb + self.heartbeat_ms / 1000.0, now)
            nxt = min(nxt, self.next_hb - now)
        timeout_s = (self.consumer & 0xFFFF) / 1000.0
        if timeout_s > 0 and self.ecu_hb is not None and not self.timed_out \
                and now - self.ecu_hb > timeout_s and self.pace == 0:
            self.timed_out = True
            self.emcy("heartbeat_lost", ERR_GENERIC | ERR_COMMUNICATION)
        return max(nxt, 0.0)

    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:  # noqa: ARG002
        if self.state != NMTState.OPERATIONAL:
            return
        m = self.frames.by_name["EMA_RPDO1"]
        if len(data) != m.length:
            self.bad_frames += 1
            return
        sig: Any = m.decode(bytes(data), decode_choices=False)
        demand = float(sig["CurrentDemand"])
        control = int(sig["ControlWord"])
        if (control & ControlWord.FAULT_RESET and not self.pending[1] & ControlWord.FAULT_RESET
                and self.timed_out):
            self.timed_out = False
        ok = math.isfinite(demand)
        self.pending = (demand if ok else 0.0, control, not ok)

    def rig_load(self) -> float:
        """The rig's axial force over the coming period (N)."""
        if not self.load_n:
            return 0.0
        t = self.act.k * self.act.period_s
        return self.load_n * math.sin(2.0 * math.pi * self.load_hz * t)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:  # noqa: ARG002
        if self.state != NMTState.OPERATIONAL:
            return
        demand, control, clamped = self.pending
        enabled = bool(control & ControlWord.ENABLE) and not self.timed_out
        s = self.act.sample()
        cpr = self.act.params.encoder_counts
        status = (STATUS_ENABLED if enabled else 0) | (STATUS_DEMAND_CLAMPED if clamped else 0)
        status |= STATUS_COMMAND_TIMEOUT if self.timed_out else 0
        values = {"MotorCurrent": s[0], "StatusWord": status,
                  "EncoderAngle": round(s[1] * cpr / (2.0 * math.pi)),
                  "EncoderSpeed": s[2], "LvdtPosition": s[3],
                  "WindingTemperature": WINDING_K, "LoadForce": s[4]}
        for name in TPDOS:
            self.send(self.frames.encode(name, {
                sg.name: self.frames.clamp(name, sg.name, values[sg.name])
                for sg in self.frames.by_name[name].signals}))
        self.act.step(demand if enabled else 0.0, self.rig_load())

    def emcy(self, label: str, register: int) -> None:
        code = self.frames.choice("EMA_EMCY", "EMCY_ErrorCode", label)
        self.send(self.frames.encode("EMA_EMCY", {
            "EMCY_ErrorCode": code, "EMCY_ErrorRegister": register,
            "EMCY_StatusWord": STATUS_COMMAND_TIMEOUT if self.timed_out else 0,
            "EMCY_Cycle": 0}))

    def _on_sdo_read(self, index: int, subindex: int, od) -> int | None:  # noqa: ARG002
        if index == 0x1001:
            return ERR_GENERIC | ERR_COMMUNICATION if self.timed_out else 0
        if index == 0x1006:
            return int(round(self.act.period_s * 1e6))
        if (index, subindex) == (0x2200, 1):
            return self.pace
        return None

    def _on_sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:
        raw = od.decode_raw(data)
        if index == 0x1006 and raw != int(round(self.act.period_s * 1e6)):
            raise SdoAbortedError(ABORT_VALUE_RANGE)
        if 0x1400 <= index <= 0x1BFF:
            raise SdoAbortedError(ABORT_READ_ONLY)
        if index == 0x1017:
            self.heartbeat_ms = int(raw)
            self.next_hb = self.clock() + self.heartbeat_ms / 1000.0
        elif (index, subindex) == (0x1016, 1):
            self.consumer = int(raw)
        elif index == 0x2200:
            self._node_control(subindex, int(raw))

    def _node_control(self, sub: int, raw: int) -> None:
        """0x2200: sub 1 pace (0 real time, 1 lockstep: the consumer then counts nothing
        on the wall clock), sub 2 restart the physics at t = 0 (pre-operational only)."""
        if sub == 1:
            if raw not in (0, 1) or self.state == NMTState.OPERATIONAL:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self.pace = raw
        elif sub == 2 and raw == 1:
            if self.state == NMTState.OPERATIONAL:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self.act.reset()

    def send(self, msg: can.Message) -> None:
        self.bus.send(msg)

    def handle(self, msg: can.Message) -> None:
        """One received frame; a frame that does not decode is counted, never raised."""
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        cid = msg.arbitration_id
        if cid == 0x700 + (self.consumer >> 16 & 0x7F):
            self.ecu_hb = self.clock()
            return
        if cid == self.local.sdo.rx_cobid and (self.state == NMTState.STOPPED
                                               or len(msg.data) != 8):
            return
        try:
            self.network.notify(cid, msg.data, msg.timestamp)
        except Exception:  # noqa: BLE001 - a frame never stops the node
            self.bad_frames += 1

    def serve(self, duration_s: float | None = None,
              alive: Callable[[], bool] | None = None) -> None:
        """Boot, then serve the bus until `stop()`, `duration_s` or `alive()` is False."""
        self.running = True
        end = None if duration_s is None else self.clock() + duration_s
        next_check = 0.0
        self.boot()
        while self.running:
            now = self.clock()
            if end is not None and now >= end:
                break
            if alive is not None and now >= next_check:
                next_check = now + 0.25
                if not alive():
                    break
            msg = self.bus.recv(timeout=min(0.05, self.timers()))
            if msg is not None:
                self.handle(msg)

    def stop(self) -> None:
        self.running = False
