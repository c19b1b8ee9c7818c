"""The plant node's heartbeat (CiA 301 NMT error control) beyond the producer (0x1017,
`ema_contract.node.CanopenNode`): the consumer of the ECU's heartbeat (0x1016) on the node's time base (SYNC periods in
lockstep, the wall clock in real time), and the error behaviour on a lost heartbeat
(0x1029 sub 1) and its clearing by a fault reset.

`Heartbeat` is a part of `plant_rt.node.PlantNode` (a mixin): it uses the node's state,
clock, counters and EMCY producer, and is not used on its own.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import can

from ema_contract.states import NMTState, Pace
from plant_rt.nodebase import NodePart
from plant_rt.ratelimit import EPS_S

# error behaviour 0x1029 sub 1 (CiA 301): on a communication error (heartbeat lost)
ERROR_BEHAVIOUR_PRE_OPERATIONAL, ERROR_BEHAVIOUR_NONE, ERROR_BEHAVIOUR_STOPPED = 0, 1, 2


class Heartbeat(NodePart):
    """Heartbeat producer/consumer and error behaviour of `PlantNode` (module docstring)."""

    _check_conditions: Callable[[], None]     # plant_rt.emcy.EmcyProducer

    def on_ecu_heartbeat(self, msg: can.Message) -> None:
        if len(msg.data) != 1:
            self.counters.bad_frames += 1
            return
        self.ecu_hb = self.clock()
        self._syncs_since_hb = 0

    def _fault_reset(self) -> None:
        if self._timeout and self._ecu_alive():
            self._timeout = False
            self._log.log(self.node_time(), logging.INFO,
                          "command timeout cleared by fault reset")

    def _consumer_syncs(self) -> int:
        """Lockstep heartbeat consumer time in SYNC periods (consumer time / SYNC period,
        rounded up)."""
        return math.ceil(self.consumer_timeout_s() / self.period_s - EPS_S)

    def _ecu_alive(self) -> bool:
        """False once the ECU heartbeat, seen before, has been missing for longer than the
        consumer time: more SYNC periods in lockstep, wall time in real time."""
        tmo = self.consumer_timeout_s()
        if tmo <= 0:
            return True
        if self.pace == Pace.SYNC:
            n = self._syncs_since_hb
            return n is None or n <= self._consumer_syncs()
        return self.ecu_hb is None or self.clock() - self.ecu_hb < tmo

    def _consumer_timed_out(self) -> None:
        """Heartbeat lost: demand 0, status bit 4, EMCY 0x8130, then the error behaviour
        of 0x1029 sub 1 (0 PRE-OPERATIONAL if OPERATIONAL, 1 no change, 2 STOPPED)."""
        self._timeout = True
        self.counters.heartbeat_timeouts += 1
        self.applied_a = 0.0
        tmo = self.consumer_timeout_s()
        base = (f"{self._consumer_syncs()} SYNC periods" if self.pace == Pace.SYNC
                else f"{tmo * 1e3:.0f} ms")
        self._log.log(self.node_time(), logging.WARNING,
                      "ECU heartbeat lost for more than %s: demand forced to 0", base)
        self._check_conditions()
        if self._error_behaviour == ERROR_BEHAVIOUR_STOPPED:
            self.set_state(NMTState.STOPPED)
        elif (self._error_behaviour == ERROR_BEHAVIOUR_PRE_OPERATIONAL
              and self.state == NMTState.OPERATIONAL):
            self.set_state(NMTState.PRE_OPERATIONAL)

    def _consumer_timer(self, now: float, nxt: float) -> float:
        """The real-time heartbeat consumer at wall time `now`; returns `nxt` or the
        seconds to the consumer's timeout if sooner."""
        tmo = self.consumer_timeout_s()
        if (self.pace == Pace.REALTIME and tmo > 0 and self.ecu_hb is not None
                and not self._timeout):
            left = self.ecu_hb + tmo - now
            if left <= 0:
                self._consumer_timed_out()
            else:
                nxt = min(nxt, left)
        return nxt


__all__ = ["ERROR_BEHAVIOUR_NONE", "ERROR_BEHAVIOUR_PRE_OPERATIONAL",
           "ERROR_BEHAVIOUR_STOPPED", "Heartbeat"]
