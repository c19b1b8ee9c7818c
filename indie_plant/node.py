"""The independent actuator as a CANopen node that knows only `ema_contract`.

CiA 301 through `ema_contract.node.CanopenNode` (canopen's `LocalNode`) over the EDS's CiA 301 objects (0x1000-0x1FFF)
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

import can
from canopen.objectdictionary import ObjectDictionary
from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.drive import DriveNode
from ema_contract.frames import Frames
from ema_contract.node import ABORT_VALUE_RANGE, TPDOS, cia301_od
from ema_contract.states import ControlWord, NMTState
from indie_plant.generate import Actuator

WINDING_K = 293.15          # no thermal model: the winding sensor reads 20 C


def node_od(node_id: int) -> ObjectDictionary:
    """The EDS's CiA 301 objects and 0x2200 (node control); nothing else from 0x2000 on."""
    return cia301_od(node_id, keep=(0x2200,))


class IndieNode(DriveNode):
    """The node's bus side on `ema_contract.drive.DriveNode` (single-threaded: `serve()`
    reads the bus, SDO requests go to canopen's server, the rest to the hooks below)."""

    def __init__(self, bus: can.BusABC, actuator: Actuator, node_id: int | None = None,
                 load_n: float = 0.0, load_hz: float = 0.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        frames = Frames(node_id, None)
        super().__init__(bus, frames, node_od(frames.node_id), clock)
        self.act = actuator
        self.load_n, self.load_hz = load_n, load_hz
        self.on_frame(frames.cob["EMA_RPDO1"], self._on_rpdo)
        self.pace = 0
        self.on_reset_communication()

    def on_reset_node(self) -> None:
        self.act.reset()
        self.pace = 0

    def on_reset_communication(self) -> None:
        self.local.data_store.clear()          # 0x2200 too: every written object
        self.pending = (0.0, 0, False)
        self.timed_out = False

    def set_state(self, new: NMTState) -> None:
        if new == NMTState.OPERATIONAL and self.state != NMTState.OPERATIONAL:
            self.pending = (0.0, 0, False)
        super().set_state(new)

    @property
    def period_s(self) -> float:
        return self.act.period_s

    def consumer_counts(self) -> bool:
        """The heartbeat consumer counts the wall clock in real time only (pace 0)."""
        return self.pace == 0

    def _on_rpdo(self, msg: can.Message) -> None:
        if self.state != NMTState.OPERATIONAL:
            return
        _, sig = self.frames.decode(msg)  # type: ignore[misc]
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

    def on_sync(self, msg: can.Message) -> None:  # noqa: ARG002
        if self.state != NMTState.OPERATIONAL:
            return
        demand, control, clamped = self.pending
        enabled = bool(control & ControlWord.ENABLE) and not self.timed_out
        s = self.act.sample()
        cpr = self.act.params.encoder_counts
        values = {"MotorCurrent": s[0], "StatusWord": self.status_word(enabled, clamped),
                  "EncoderAngle": round(s[1] * cpr / (2.0 * math.pi)),
                  "EncoderSpeed": s[2], "LvdtPosition": s[3],
                  "WindingTemperature": WINDING_K, "LoadForce": s[4]}
        for m in self.pdo_frames(values, TPDOS):
            self.send(m)
        self.act.step(demand if enabled else 0.0, self.rig_load())

    def sdo_read(self, index: int, subindex: int, od) -> int | None:
        if (index, subindex) == (0x2200, 1):
            return self.pace
        return super().sdo_read(index, subindex, od)

    def sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:
        super().sdo_write(index, subindex, od, data)
        if index == 0x2200:
            self._node_control(subindex, int(od.decode_raw(data)))

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
