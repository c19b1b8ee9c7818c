"""The plant node's SDO object callbacks: reads and writes of the parameters (0x2000-0x2008,
`plant_rt.paramobjects`), the status counters (0x2100), the node control (0x2200), the
process data images (0x2300, 0x2400) and the communication objects it serves itself
(0x1001, 0x1006, 0x1015, 0x1018 sub 4 serial number, 0x1029; the heartbeat objects
0x1016 and 0x1017 are `ema_contract.node.CanopenNode`'s), with the CiA 301 abort codes.

`SdoObjects` is a part of `plant_rt.node.PlantNode` (a mixin): canopen's SDO server calls
these callbacks (the hooks `CanopenNode.sdo_read` / `sdo_write`); they use the node's
state, parameters, plant, counters and timers.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.node import (
    ABORT_APP_REFUSED,
    ABORT_DEVICE_STATE,
    ABORT_VALUE_HIGH,
    ABORT_VALUE_LOW,
    ABORT_VALUE_RANGE,
)
from ema_contract.states import NMTState, Pace
from plant_rt.emcy import EmcyState
from plant_rt.heartbeat import (
    ERROR_BEHAVIOUR_NONE,
    ERROR_BEHAVIOUR_PRE_OPERATIONAL,
    ERROR_BEHAVIOUR_STOPPED,
)
from plant_rt.nodebase import NodePart
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import ParameterError, PlantParams


class SdoObjects(NodePart):
    """The SDO read/write callbacks of `PlantNode` (see the module docstring)."""

    # plant_rt.emcy.EmcyProducer
    _emcy: EmcyState
    _emcy_inhibit_raw: int
    error_register: Callable[[], int]
    _set_emcy_inhibit: Callable[[int], None]

    def sdo_read(self, index: int, subindex: int, od) -> object | None:
        key = (index, subindex)
        po = self.param_objects.by_key.get(key)
        if po is not None:
            return ParamObjects.to_od(po.info, self.params.get(po.info.name))
        if index == self._status_keys["nmt_state"][0]:
            return self._status_value(od.name)
        if index == self._control_keys["pace"][0]:
            if od.name == "pace":
                return int(self.pace)
            if od.name == "spin_us":
                return self.spin_us
            return None
        if index == self._tx_keys["MotorCurrent"][0] and subindex:
            v = self._last_process or self.process_values()
            raw = v[od.name]
            return raw if od.factor == 1 else round(raw / od.factor)
        return self._read_communication(index, subindex)

    def _read_communication(self, index: int, subindex: int) -> object | None:
        """The CiA 301 communication objects the node keeps itself (None: canopen's store)."""
        key = (index, subindex)
        if index == 0x1001:
            return self.error_register()
        if index == 0x1006:
            return int(round(self.params.sim.sync_period_s * 1e6))
        if key == (0x1018, 4):
            return self.serial
        if index == 0x1015:
            return self._emcy_inhibit_raw
        if key == (0x1029, 1):
            return self._error_behaviour
        return None

    def _status_value(self, name: str) -> float | int:
        c, p = self.counters, self._pacer
        values = {
            "nmt_state": int(self.state),
            "status_word": self.status_word(self.plant.status()),
            "deadline_misses": p.misses,
            "jitter_p50_us": p.lateness.percentile_us(50),
            "jitter_p99_us": p.lateness.percentile_us(99),
            "jitter_max_us": p.lateness.max_us,
            "plant_time_s": self.plant.t,
            "applied_demand_a": self.applied_a,
            "skipped_periods": p.skipped,
            "step_time_p99_us": self.step_stats.percentile_us(99),
        }
        if name in values:
            return values[name]
        return int(getattr(c, name))

    def sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:
        key = (index, subindex)
        po = self.param_objects.by_key.get(key)
        if po is not None:
            self._write_param(po.info, od, data)
            return
        if index == self._control_keys["pace"][0]:
            self._write_control(od, data)
            return
        if index == self._rx_keys["CurrentDemand"][0]:
            raise SdoAbortedError(ABORT_APP_REFUSED)   # commands arrive by RPDO only
        self._write_communication(index, subindex, od, data)

    def _write_param(self, info, od, data: bytes) -> None:
        """A plant parameter (0x2000-0x2008): in PRE-OPERATIONAL only, checked."""
        self._require_preop()
        raw = od.decode_raw(data)
        try:
            value = ParamObjects.from_od(info, raw)
            new = self.params.with_dict({info.name: value})
        except ParameterError as exc:
            self._log.log(self.node_time(), logging.INFO, "SDO write refused: %s", exc)
            code = ABORT_VALUE_RANGE
            if isinstance(raw, (int, float)) and not isinstance(raw, bool):
                if info.max is not None and raw > info.max:
                    code = ABORT_VALUE_HIGH
                elif info.min is not None and raw < info.min:
                    code = ABORT_VALUE_LOW
            raise SdoAbortedError(code) from None
        self._apply_params(new)

    def _write_control(self, od, data: bytes) -> None:
        """Node control 0x2200: pace, reset_plant, reset_counters, spin_us."""
        raw = od.decode_raw(data)
        if od.name == "pace":
            self._require_preop()
            try:
                self.pace = Pace(raw)
            except ValueError:
                raise SdoAbortedError(ABORT_VALUE_RANGE) from None
            self.node_time()              # the node clock may change its base
        elif od.name == "reset_plant":
            self._require_preop()
            if raw != 1:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self.plant = self._plant_factory(self.params)
            self._sensor_cache = None
            self.counters.cycles = 0
            self._emcy = EmcyState()
        elif od.name == "reset_counters":
            if raw != 1:
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self.counters.reset()
            self._pacer.reset_stats()
            self.step_stats.reset()
        elif od.name == "spin_us":
            if not 0 <= raw <= self.period_s * 1e6:
                raise SdoAbortedError(ABORT_VALUE_HIGH)
            self.spin_us = int(raw)
            self._pacer.spin_ns = int(raw) * 1000

    def _write_communication(self, index: int, subindex: int, od, data: bytes) -> None:
        """The communication objects served here: 0x1006, 0x1015, 0x1029."""
        key = (index, subindex)
        if index == 0x1006:
            self._require_preop()
            raw = od.decode_raw(data)
            try:
                new = self.params.with_dict({"sim.sync_period_s": raw * 1e-6})
            except ParameterError:
                raise SdoAbortedError(ABORT_VALUE_RANGE) from None
            self._apply_params(new)
            return
        if index == 0x1015:
            self._set_emcy_inhibit(od.decode_raw(data))
            return
        if key == (0x1029, 1):
            raw = int(od.decode_raw(data))
            if raw not in (ERROR_BEHAVIOUR_PRE_OPERATIONAL, ERROR_BEHAVIOUR_NONE,
                           ERROR_BEHAVIOUR_STOPPED):
                raise SdoAbortedError(ABORT_VALUE_RANGE)
            self._error_behaviour = raw
            return

    def _require_preop(self) -> None:
        if self.state != NMTState.PRE_OPERATIONAL:
            raise SdoAbortedError(ABORT_DEVICE_STATE)

    def _apply_params(self, new: PlantParams) -> None:
        period_changed = new.sim.sync_period_s != self.params.sim.sync_period_s
        self.params = new
        self.plant.set_params(new)
        self._sensor_cache = None
        if period_changed:
            self._pacer = self._new_pacer()


__all__ = ["ABORT_APP_REFUSED", "ABORT_DEVICE_STATE", "ABORT_VALUE_HIGH", "ABORT_VALUE_LOW",
           "ABORT_VALUE_RANGE", "SdoObjects"]
