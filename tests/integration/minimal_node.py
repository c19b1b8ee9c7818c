"""A test double of a vendor's actuator node: CiA 301 and the PDOs of
`dbc/ema.dbc`, nothing else (docs/node-contract.md is the contract it implements).

Two parts, kept apart so that a node with other physics can reuse the bus part:

- `MinimalNode` (bus, on the bench's node base `ema_contract.node.CanopenNode`): NMT
  slave, boot-up, heartbeat producer (0x1017) and consumer
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
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import can
import can.cli

from ema_contract.drive import DriveNode
from ema_contract.frames import Frames, exclude_filters
from ema_contract.node import TPDOS, cia301_od
from ema_contract.states import ControlWord, NMTState

TWO_PI = 2.0 * math.pi


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
class MinimalNode(DriveNode):
    """A CiA 301 node with the DBC's PDOs, driving `physics` (see module docstring), on
    `ema_contract.drive.DriveNode`: NMT, heartbeat producer and consumer, SDO server, EMCY,
    SYNC dispatch and the loop are the base's; this class adds RPDO1 and the TPDOs.

    Single-threaded: `serve()` reads the bus, hands SDO requests to canopen's server and
    the other frames to the hooks below, and produces the heartbeat."""

    def __init__(self, bus: can.BusABC, physics: Physics, node_id: int | None = None,
                 ecu_id: int | None = None, clock: Callable[[], float] = time.monotonic,
                 identity: bool = True) -> None:
        frames = Frames(node_id, ecu_id)
        super().__init__(bus, frames, cia301_od(frames.node_id, identity=identity), clock)
        self.physics = physics
        self.on_frame(frames.cob["EMA_RPDO1"], self._on_rpdo)
        self.on_reset_communication()

    # -- NMT and heartbeat ------------------------------------------------------------------
    def on_reset_node(self) -> None:
        self.physics.reset()

    def on_reset_communication(self) -> None:
        self.pending = (0.0, 0, False)         # (demand A, control word, clamped) of RPDO1
        self.held = (0.0, 0, False)            # the command in force since the last SYNC
        self.timed_out = False

    def set_state(self, new: NMTState) -> None:
        if new == NMTState.OPERATIONAL and self.state != NMTState.OPERATIONAL:
            self.pending = self.held = (0.0, 0, False)
        super().set_state(new)

    @property
    def period_s(self) -> float:
        return self.physics.period_s

    # -- process data -----------------------------------------------------------------------
    def _on_rpdo(self, msg: can.Message) -> None:
        if self.state != NMTState.OPERATIONAL:
            return
        _, sig = self.frames.decode(msg)  # type: ignore[misc]
        demand = float(sig["CurrentDemand"])
        clamped = not math.isfinite(demand)
        control = int(sig["ControlWord"])
        # a fault-reset edge clears a command timeout while the ECU's heartbeat is current
        # (node-contract.md, Heartbeat)
        if (control & ControlWord.FAULT_RESET and not self.pending[1] & ControlWord.FAULT_RESET
                and self.timed_out and self.ecu_hb is not None
                and self.clock() - self.ecu_hb <= self.consumer_timeout_s()):
            self.timed_out = False
        self.pending = (0.0 if clamped else demand, control, clamped)

    def on_sync(self, msg: can.Message) -> None:  # noqa: ARG002
        if self.state != NMTState.OPERATIONAL:
            return
        self.held = self.pending
        demand, control, clamped = self.held
        enabled = bool(control & ControlWord.ENABLE) and not self.timed_out
        values, status = self.physics.sample()
        status |= self.status_word(enabled, clamped)
        for m in self.pdo_frames({**values, "StatusWord": status}, TPDOS):
            self.send(m)
        self.physics.step(demand if enabled else 0.0)


# -- process ------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    from ema_contract.drive import serve_process
    from ema_contract.transport import open_bus
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
    serve_process(node, args.ready_file, args.parent_pid, args.duration)
    return 0


if __name__ == "__main__":
    sys.exit(main())
