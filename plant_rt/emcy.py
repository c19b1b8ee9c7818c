"""The plant node's EMCY producer (CiA 301): the error register (0x1001), EMCY frames on
rising and cleared conditions, held back by the inhibit time (0x1015) in a queue of one
event per error code (`plant_rt.ratelimit.Inhibit`).

`EmcyProducer` is a part of `plant_rt.node.PlantNode` (a mixin): it uses the node's
frames, counters, clock, plant and status word, and is not used on its own.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from ema_contract.node import (  # the error register bits (CiA 301 0x1001)
    ERR_COMMUNICATION,
    ERR_CURRENT,
    ERR_GENERIC,
    ERR_MANUFACTURER,
    ERR_TEMPERATURE,
)
from ema_contract.states import StatusWord
from plant_rt.nodebase import NodePart
from plant_rt.ratelimit import Inhibit

log = logging.getLogger("plant_rt.node")    # the node's logger: one name for its lines


# condition -> (DBC EMCY value-table label, error register bits)
EMCY_CONDITIONS: dict[StatusWord, tuple[str, int]] = {
    StatusWord.OVERCURRENT: ("overcurrent", ERR_CURRENT),
    StatusWord.END_OF_STROKE: ("end_of_stroke", ERR_MANUFACTURER),
    StatusWord.OVERTEMPERATURE: ("overtemperature", ERR_TEMPERATURE),
    StatusWord.PLANT_FAULT: ("plant_fault", ERR_MANUFACTURER),
    StatusWord.COMMAND_TIMEOUT: ("heartbeat_lost", ERR_COMMUNICATION),
    StatusWord.DEMAND_CLAMPED: ("demand_invalid", ERR_MANUFACTURER),
}
_CONDITIONS = [(int(c), label, bits) for c, (label, bits) in EMCY_CONDITIONS.items()]
EMCY_REARM_S = 0.1   # plant time a condition must stay clear before it counts as cleared


@dataclass
class EmcyState:
    """Active EMCY conditions and, for those seen clear, since when (plant time, s)."""
    active: StatusWord = StatusWord.NONE
    off_since: dict[int, float] = field(default_factory=dict)


class EmcyProducer(NodePart):
    """EMCY production of `PlantNode` (see the module docstring)."""

    _emcy: EmcyState
    _emcy_inhibit: Inhibit
    _emcy_inhibit_raw: int

    def error_register(self) -> int:
        reg = 0
        active = int(self._emcy.active)
        for cond, _, bits in _CONDITIONS:
            if active & cond:
                reg |= bits | ERR_GENERIC
        return reg

    def emcy(self, label: str, register: int | None = None) -> None:
        """Raise EMCY `label` (DBC value table) with the state now; sent at once, or when
        the inhibit time (0x1015) ends, replacing a waiting EMCY with the same code."""
        reg = self.error_register() if register is None else register
        status = self.status_word(self.plant.status())
        values = self.emcy_values(label, reg, status, self.counters.cycles % (1 << 24))
        code = values["EMCY_ErrorCode"]
        if self._emcy_inhibit.add(code, (label, code, values)):
            self.counters.emcy_suppressed += 1
        self._send_due_emcy(self.node_time())

    def _send_due_emcy(self, now_s: float) -> None:
        self._send_emcy(self._emcy_inhibit.due(now_s))

    def _send_emcy(self, items: list[tuple[object, int]]) -> None:
        for item, repeats in items:
            label: str
            code: int
            values: dict[str, int]
            label, code, values = item  # type: ignore[misc]
            self.send(self.frames.encode("EMA_EMCY", values))   # encoded when sent only
            self.counters.emcy_sent += 1
            if repeats:
                log.warning("EMCY %s (0x%04X), %d repeats suppressed", label, code, repeats)
            else:
                log.warning("EMCY %s (0x%04X)", label, code)

    def _set_emcy_inhibit(self, units_100us: int) -> None:
        """EMCY inhibit time (0x1015, 100 us units); the log rate limit follows it."""
        self._emcy_inhibit_raw = int(units_100us)
        self._emcy_inhibit.inhibit_s = self._log.window_s = int(units_100us) * 100e-6

    def _check_conditions(self) -> None:
        """EMCY on a rising condition; a condition counts as cleared (and, when none is
        left, EMCY "no_error" is sent) only after EMCY_REARM_S of plant time off, so a
        drive chattering at its current limit does not flood the bus."""
        st = self.status_word(self.plant.status())
        es = self._emcy
        active = int(es.active)
        if not st and not active:
            return
        now = self.plant.t
        for cond, label, bits in _CONDITIONS:
            if st & cond:
                es.off_since.pop(cond, None)
                if not active & cond:
                    active |= cond
                    es.active = StatusWord(active)
                    self.emcy(label, self.error_register() | bits | ERR_GENERIC)
            elif active & cond:
                t0 = es.off_since.setdefault(cond, now)
                if now - t0 >= EMCY_REARM_S:
                    active &= ~cond
                    es.active = StatusWord(active)
                    del es.off_since[cond]
                    if not active:
                        self.emcy("no_error", 0)


__all__ = ["EMCY_CONDITIONS", "EMCY_REARM_S", "ERR_COMMUNICATION", "ERR_CURRENT",
           "ERR_GENERIC", "ERR_MANUFACTURER", "ERR_TEMPERATURE", "EmcyProducer", "EmcyState"]
