"""The EDS's plant parameter objects (0x2000-0x2008) <-> `plant_rt.params`.

One record per parameter group, one sub-index per parameter (as `plant_rt.eds` writes
them); `ParamObjects` finds them in an object dictionary (`ema_contract.frames.load_od`)
and converts values both ways. The simulated plant's node serves them; the ECU and the
log decoder use them to set and read the plant's parameters over SDO.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from plant_rt.params import PARAMS, ParameterError, ParamInfo, check_value


@dataclass(frozen=True)
class ParamObject:
    """One plant parameter as an SDO object."""
    index: int
    subindex: int
    info: ParamInfo


class ParamObjects:
    """The EDS's parameter objects (record per group, sub-index per leaf) by name."""

    def __init__(self, od) -> None:
        by_name = {p.name: p for p in PARAMS}
        self.by_key: dict[tuple[int, int], ParamObject] = {}
        self.by_name: dict[str, ParamObject] = {}
        for obj in od.values():
            if not (0x2000 <= obj.index < 0x2100) or not hasattr(obj, "subindices"):
                continue
            for sub, var in obj.subindices.items():
                name = f"{obj.name}.{var.name}"
                if sub == 0 or name not in by_name:
                    continue
                po = ParamObject(obj.index, sub, by_name[name])
                self.by_key[(obj.index, sub)] = po
                self.by_name[name] = po
        missing = set(by_name) - set(self.by_name)
        if missing:
            raise ValueError(f"the EDS lacks parameter objects for {sorted(missing)}; "
                             "run python -m plant_rt.eds")

    @staticmethod
    def to_od(info: ParamInfo, value: Any) -> Any:
        """A checked parameter value as the object's raw value (choices by index)."""
        v = check_value(info, value)
        if info.type is str:
            return (info.choices or ()).index(v)
        if info.type is bool:
            return bool(v)
        if info.type is int:
            return int(v)
        return float(v)

    @staticmethod
    def from_od(info: ParamInfo, raw: Any) -> Any:
        """The parameter value of an object's raw value (ParameterError if invalid)."""
        if info.type is str:
            choices = info.choices or ()
            if not isinstance(raw, int) or not 0 <= raw < len(choices):
                raise ParameterError(f"{info.name}: choice index {raw!r} is not one of "
                                     f"0..{len(choices) - 1}")
            return choices[raw]
        return check_value(info, raw)
