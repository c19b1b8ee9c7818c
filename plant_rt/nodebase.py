"""What the parts of the plant node share: its counters (object 0x2100), the ECU command
it latches, and `NodePart`, the typed interface of `plant_rt.node.PlantNode` (on
`ema_contract.node.CanopenNode`) that its parts (`plant_rt.emcy`, `plant_rt.heartbeat`, `plant_rt.sdoobjects`) use.

`NodePart` only declares (annotations, no values, no behaviour): `PlantNode` sets and
implements everything; the declarations let the parts be checked on their own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import can

from ema_contract.frames import Frames
from ema_contract.node import FrameCounters
from ema_contract.states import ControlWord, NMTState, Pace
from plant_rt.model import Plant
from plant_rt.pacing import LatenessStats, RealtimePacer
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import PlantParams
from plant_rt.ratelimit import LogLimiter


@dataclass
class Counters(FrameCounters):
    """What object 0x2100 reports (reset by NMT reset and by 0x2200 sub 3): the frame
    counters of `ema_contract.node.FrameCounters`, then the plant's."""
    demands_invalid: int = 0
    sync_received: int = 0
    cycles: int = 0
    heartbeat_timeouts: int = 0
    emcy_sent: int = 0
    rpdo_missing: int = 0
    sync_counter_gaps: int = 0
    emcy_suppressed: int = 0


@dataclass
class Command:
    """The ECU's command as received (RPDO1) and as latched at a SYNC."""
    demand_a: float = 0.0
    control: ControlWord = ControlWord.NONE
    invalid: bool = False   # NaN/inf or beyond the current limit (replaced/clamped)


class NodePart:
    """The attributes and core methods of `PlantNode` its parts use (declarations only)."""

    frames: Frames
    param_objects: ParamObjects
    _status_keys: dict[str, tuple[int, int]]
    _control_keys: dict[str, tuple[int, int]]
    _tx_keys: dict[str, tuple[int, int]]
    _rx_keys: dict[str, tuple[int, int]]
    _plant_factory: Callable[[PlantParams], Plant]
    clock: Callable[[], float]
    params: PlantParams
    plant: Plant
    pace: Pace
    spin_us: int
    counters: Counters
    state: NMTState
    applied_a: float
    _timeout: bool
    _log: LogLimiter
    _pacer: RealtimePacer
    step_stats: LatenessStats
    _last_process: dict[str, float | int] | None
    _sensor_cache: tuple[dict[str, float | int], list[can.Message], int] | None
    heartbeat_ms: int
    serial: int
    next_hb: float
    consumer: int
    _error_behaviour: int
    ecu_hb: float | None
    _syncs_since_hb: int | None
    send: Callable[[can.Message], None]
    node_time: Callable[[], float]
    status_word: Callable[[int], int]
    process_values: Callable[[], dict[str, float | int]]
    set_state: Callable[[NMTState], None]
    consumer_timeout_s: Callable[[], float]
    _new_pacer: Callable[[], RealtimePacer]

    if TYPE_CHECKING:     # ema_contract.node.CanopenNode's (after NodePart in the MRO)
        def emcy_values(self, label: str, register: int, status_word: int = 0,
                        cycle: int = 0) -> dict[str, int]: ...

    @property
    def period_s(self) -> float:
        raise NotImplementedError


__all__ = ["Command", "Counters", "NodePart"]
