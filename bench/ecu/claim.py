"""The ECU's claim on the node: no other ECU drives it; receive checks, abort."""

from __future__ import annotations

import time
from collections.abc import Callable

import can

from bench.ecu.errors import BusLost, ForeignEcu
from bench.ecu.link import ECU_FRAMES
from bench.ecu.prepare import NodePrepare
from ema_contract.states import NMTCommand, NMTState


class EcuClaim(NodePrepare):
    """Foreign-producer watch and the claim on the node, the run's receive checks, abort."""

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

    # -- claim, checks and abort -------------------------------------------------
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
