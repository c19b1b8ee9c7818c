"""A test double of a vendor's actuator node: CiA 301 and the PDOs of
`dbc/ema.dbc`, nothing else (docs/node-contract.md is the contract it implements).

Two parts, kept apart so that a node with other physics can reuse the bus part:

- `MinimalNode` (bus): NMT slave, boot-up, heartbeat producer (0x1017) and consumer
  (0x1016), an SDO server (canopen `LocalNode`) over an object dictionary holding only
  the CiA 301 objects of `dbc/ema.eds` (0x1000-0x1FFF: device type, error register,
  identity, SYNC period, EMCY, heartbeat, PDO communication and mapping parameters),
  RPDO1 in, TPDO1-3 and EMCY out, frames encoded with cantools from the DBC. None of the
  simulated plant's objects (0x2000-0x2400) exist: an SDO access to them gets CiA 301's
  abort 0x06020000 (object does not exist), as from a real actuator.
- `Physics` (what the node drives): `PlantPhysics` puts `plant_rt.model.Plant` (public
  model API) behind it.

SYNC-driven, like a drive whose loop is synchronised to SYNC (CiA 301 synchronous PDOs):
at each SYNC in OPERATIONAL the node latches the RPDO received since the previous SYNC
as the demand in force, sends TPDO1-3 with the sensors sampled at that SYNC, then
advances the physics one SYNC period (0x1006) holding that demand: the period up to
the next SYNC, computed right after the TPDOs are out. The physics therefore advances
exactly one period per SYNC, whatever the SYNC rate; the node has no pace object (it
cannot be told to run on its own clock) and says nothing about being SYNC-driven.

Run: ``python tests/integration/minimal_node.py -i remote -c ws://127.0.0.1:PORT/``.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import can
import can.cli
import canopen
from canopen.objectdictionary import ObjectDictionary
from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.frames import Frames, exclude_filters, load_od
from ema_contract.states import ControlWord, NMTCommand, NMTState

TWO_PI = 2.0 * math.pi
ABORT_VALUE_RANGE = 0x06090030      # CiA 301: invalid value for parameter
ABORT_READ_ONLY = 0x06010002        # CiA 301: attempt to write a read-only object
STATUS_COMMAND_TIMEOUT = 0x10       # TPDO1 StatusWord bits (dbc/ema.dbc comment)
STATUS_DEMAND_CLAMPED = 0x20
STATUS_ENABLED = 0x40
ERR_GENERIC, ERR_COMMUNICATION = 0x01, 0x10   # 0x1001 error register bits
TPDOS = ("EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3")


# -- physics ------------------------------------------------------------------------------
class Physics(Protocol):
    """What the bus part drives: one call to `step` per SYNC period."""
    period_s: float     # SYNC period (s), what 0x1006 reports

    def reset(self) -> None:
        """Back to the power-on state (NMT reset node)."""

    def step(self, demand_a: float) -> None:
        """Advance one period holding the current demand `demand_a` (A)."""

    def sample(self) -> tuple[dict[str, float], int]:
        """(sensor signals by DBC signal name in DBC units, status bits 0-3) now."""


class PlantPhysics:
    """`plant_rt.model.Plant` behind the `Physics` interface (the simulated actuator)."""

    def __init__(self, params=None) -> None:
        from plant_rt.model import Plant
        from plant_rt.params import PlantParams
        self.params = params or PlantParams()
        self.plant = Plant(self.params)
        self.period_s = self.params.sim.sync_period_s
        self.counts_per_rev = self.params.sensors.encoder_counts_per_rev

    def reset(self) -> None:
        self.plant.reset()

    def step(self, demand_a: float) -> None:
        self.plant.step(demand_a)

    def sample(self) -> tuple[dict[str, float], int]:
        m = self.plant.measure()
        angle = m.motor_angle_rad
        counts = round(angle * self.counts_per_rev / TWO_PI) if math.isfinite(angle) else 0
        return ({"MotorCurrent": m.current_a, "EncoderAngle": counts,
                 "EncoderSpeed": m.motor_speed_rad_s, "LvdtPosition": m.position_m,
                 "WindingTemperature": m.temperature_k, "LoadForce": m.load_n},
                int(m.status) & 0xF)


# -- bus ----------------------------------------------------------------------------------
def cia301_od(node_id: int, identity: bool = True) -> ObjectDictionary:
    """The EDS's object dictionary without anything from 0x2000 on (CiA 301 objects only);
    without the identity object 0x1018 too unless `identity`."""
    od = load_od(node_id)
    for index in [i for i in od.keys() if isinstance(i, int)
                  and (i >= 0x2000 or i == 0x1018 and not identity)]:
        del od[index]
    return od


class MinimalNode:
    """A CiA 301 node with the DBC's PDOs, driving `physics` (see module docstring).

    Single-threaded: `serve()` reads the bus, hands every frame to canopen
    (`Network.notify`: SDO server and the handlers below) and produces the heartbeat."""

    def __init__(self, bus: can.BusABC, physics: Physics, node_id: int | None = None,
                 ecu_id: int | None = None, clock: Callable[[], float] = time.monotonic,
                 identity: bool = True) -> None:
        self.bus = bus
        self.physics = physics
        self.frames = Frames(node_id, ecu_id)
        self.node_id = self.frames.node_id
        self.od = cia301_od(self.node_id, identity)
        self.local = canopen.LocalNode(self.node_id, self.od)
        self.network = canopen.Network(bus)
        self.network.add_node(self.local)
        # NMT and heartbeat from this loop (a stalled node stops its heartbeat)
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
        self._reset_communication_state()

    # -- NMT and heartbeat ------------------------------------------------------------------
    def _reset_communication_state(self) -> None:
        self.local.data_store.clear()          # written objects back to their EDS defaults
        self.heartbeat_ms = int(self.od[0x1017].default)
        self.consumer = int(self.od[0x1016][1].default)
        self.pending = (0.0, 0, False)         # (demand A, control word, clamped) of RPDO1
        self.held = (0.0, 0, False)            # the command in force since the last SYNC
        self.ecu_hb: float | None = None
        self.timed_out = False
        self.next_hb = 0.0

    def boot(self) -> None:
        """Boot-up frame, then PRE-OPERATIONAL with the heartbeat running."""
        self.send(self.frames.encode("EMA_Heartbeat", {"EMA_NMTState": 0}))
        self.state = NMTState.PRE_OPERATIONAL
        self.next_hb = self.clock() + self.heartbeat_ms / 1000.0

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:  # noqa: ARG002
        if len(data) != 2 or data[1] not in (0, self.node_id):
            return
        cmd = data[0]
        if cmd == NMTCommand.RESET_NODE:
            self.physics.reset()
        if cmd in (NMTCommand.RESET_NODE, NMTCommand.RESET_COMMUNICATION):
            self._reset_communication_state()
            self.boot()
        elif cmd == NMTCommand.START:
            if self.state != NMTState.OPERATIONAL:
                self.pending = self.held = (0.0, 0, False)
            self.state = NMTState.OPERATIONAL
        elif cmd == NMTCommand.STOP:
            self.state = NMTState.STOPPED
        elif cmd == NMTCommand.ENTER_PRE_OPERATIONAL:
            self.state = NMTState.PRE_OPERATIONAL

    def timers(self) -> float:
        """Heartbeat production and consumption; returns seconds to the next timer."""
        now = self.clock()
        nxt = 0.05
        if self.heartbeat_ms > 0:
            if now >= self.next_hb:
                self.send(self.frames.encode("EMA_Heartbeat", {"EMA_NMTState": int(self.state)}))
                self.next_hb = max(self.next_hb + self.heartbeat_ms / 1000.0, now)
            nxt = min(nxt, self.next_hb - now)
        timeout_s = (self.consumer & 0xFFFF) / 1000.0
        if timeout_s > 0 and self.ecu_hb is not None and not self.timed_out:
            if now - self.ecu_hb > timeout_s:      # ECU lost: demand 0 until NMT reset
                self.timed_out = True
                self.emcy("heartbeat_lost", ERR_GENERIC | ERR_COMMUNICATION)
        return max(nxt, 0.0)

    # -- process data -----------------------------------------------------------------------
    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:  # noqa: ARG002
        if self.state != NMTState.OPERATIONAL:
            return
        m = self.frames.by_name["EMA_RPDO1"]
        if len(data) != m.length:
            self.bad_frames += 1
            return
        sig = m.decode(bytes(data), decode_choices=False)
        demand = float(sig["CurrentDemand"])
        clamped = not math.isfinite(demand)
        control = int(sig["ControlWord"])
        # a fault-reset edge clears a command timeout while the ECU's heartbeat is current
        # (node-contract.md, Heartbeat)
        if (control & ControlWord.FAULT_RESET and not self.pending[1] & ControlWord.FAULT_RESET
                and self.timed_out and self.ecu_hb is not None
                and self.clock() - self.ecu_hb <= (self.consumer & 0xFFFF) / 1000.0):
            self.timed_out = False
        self.pending = (0.0 if clamped else demand, control, clamped)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:  # noqa: ARG002
        if self.state != NMTState.OPERATIONAL:
            return
        self.held = self.pending
        demand, control, clamped = self.held
        enabled = bool(control & ControlWord.ENABLE) and not self.timed_out
        values, status = self.physics.sample()
        status |= (STATUS_ENABLED if enabled else 0) | (STATUS_DEMAND_CLAMPED if clamped else 0)
        status |= STATUS_COMMAND_TIMEOUT if self.timed_out else 0
        values = {**values, "StatusWord": status}
        for name in TPDOS:
            self.send(self.frames.encode(name, {
                s.name: self.frames.clamp(name, s.name, values[s.name])
                for s in self.frames.by_name[name].signals}))
        self.physics.step(demand if enabled else 0.0)

    def emcy(self, label: str, register: int) -> None:
        code = self.frames.choice("EMA_EMCY", "EMCY_ErrorCode", label)
        self.send(self.frames.encode("EMA_EMCY", {
            "EMCY_ErrorCode": code, "EMCY_ErrorRegister": register,
            "EMCY_StatusWord": STATUS_COMMAND_TIMEOUT if self.timed_out else 0,
            "EMCY_Cycle": 0}))

    # -- SDO ----------------------------------------------------------------------------------
    def _on_sdo_read(self, index: int, subindex: int, od) -> int | None:  # noqa: ARG002
        if index == 0x1001:
            return ERR_GENERIC | ERR_COMMUNICATION if self.timed_out else 0
        if index == 0x1006:
            return int(round(self.physics.period_s * 1e6))
        return None

    def _on_sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:
        raw = od.decode_raw(data)
        if index == 0x1006 and raw != int(round(self.physics.period_s * 1e6)):
            raise SdoAbortedError(ABORT_VALUE_RANGE)   # the period is the physics'
        if 0x1400 <= index <= 0x1BFF:
            raise SdoAbortedError(ABORT_READ_ONLY)     # static PDOs: those of the DBC
        if index == 0x1017:
            self.heartbeat_ms = int(raw)
            self.next_hb = self.clock() + self.heartbeat_ms / 1000.0
        elif (index, subindex) == (0x1016, 1):
            self.consumer = int(raw)

    # -- loop ---------------------------------------------------------------------------------
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


# -- process ------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    from ema_contract.transport import close_bus, open_bus, pid_alive
    from plant_rt.params import PlantParams
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    can.cli.add_bus_arguments(p)
    p.add_argument("--node-id", type=lambda s: int(s, 0), default=None)
    p.add_argument("--set", dest="assignments", action="append", default=[],
                   help="physics parameter NAME=VALUE (the vendor's hardware, not on the bus)")
    p.add_argument("--ready-file", type=Path)
    p.add_argument("--parent-pid", type=int)
    p.add_argument("--duration", type=float)
    p.add_argument("--no-identity", action="store_true",
                   help="a node without the identity object 0x1018 (no serial number)")
    args = p.parse_args(argv)
    physics = PlantPhysics(PlantParams().with_assignments(args.assignments))
    physics.step(0.0)                  # load the compiled plant before going on the bus
    physics.reset()
    cfg = {"interface": args.interface, "channel": args.channel}
    setpoint = Frames(args.node_id).cob["ECU_Setpoint"]   # for loggers, not for the drive
    bus = open_bus(cfg, receive_own_messages=False, can_filters=exclude_filters([setpoint]))
    node = MinimalNode(bus, physics, args.node_id, identity=not args.no_identity)
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *_: node.stop())
    try:
        if args.ready_file:
            args.ready_file.write_text(f"{os.getpid()}\n")
        parent = args.parent_pid
        node.serve(args.duration, (lambda: pid_alive(parent)) if parent else None)
    finally:
        close_bus(bus)
    return 0


if __name__ == "__main__":
    sys.exit(main())
