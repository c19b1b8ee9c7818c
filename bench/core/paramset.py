"""Parameter sets outside the plant (the ECU controller's, ...) with the plant's treatment.

A set is a frozen dataclass whose fields are declared with `plant_rt.params.P` (unit in
the field name and in the metadata, valid range, source, one-line description) and that
derives from `ParamSet`. Like `PlantParams` it validates itself on construction with the
plant's `check_value` (NaN, out-of-range, wrong type), lists its `ParamInfo`s, reports
`diff()`s, round-trips through JSON and refuses unknown names. Errors are
`ParamSetError`: a `ParameterError` (as the plant's) that the CLI prints as one line.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import fields
from typing import Any, ClassVar, Self

from bench import BenchError
from plant_rt.params import ParameterError, ParamInfo, check_value
from plant_rt.paramvalues import json_object, same_value

_TYPES = {"float": float, "int": int, "bool": bool, "str": str}


class ParamSetError(BenchError, ParameterError):
    """A parameter of a `ParamSet` is unknown or has an invalid value."""


class ParamSet:
    """Mixin of frozen `P(...)`-field dataclasses; `_group` prefixes the parameter names."""
    _group: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for info in self.infos():
            try:
                value = check_value(info, getattr(self, info.leaf))
            except ParameterError as exc:
                raise ParamSetError(str(exc)) from None
            object.__setattr__(self, info.leaf, value)

    @classmethod
    def infos(cls) -> list[ParamInfo]:
        """One `ParamInfo` per field (dotted name ``group.leaf``), in field order."""
        out = []
        for f in fields(cls):  # type: ignore[arg-type]
            m = f.metadata
            typ = _TYPES[f.type] if isinstance(f.type, str) else f.type
            out.append(ParamInfo(f"{cls._group}.{f.name}", cls._group, f.name, typ, f.default,
                                 m["unit"], m["min"], m["max"], m["doc"], m["source"],
                                 m["choices"]))
        return out

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    def to_json(self, indent: int = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        """From ``{leaf: value}`` (or ``{"group.leaf": value}``); unknown names refused."""
        known = {i.leaf for i in cls.infos()}
        values = {}
        for k, v in data.items():
            leaf = k[len(cls._group) + 1:] if k.startswith(f"{cls._group}.") else k
            if leaf not in known:
                raise ParamSetError(f"unknown {cls._group} parameter {k!r} (known: "
                                    f"{', '.join(sorted(known))})")
            values[leaf] = v
        return cls(**values)

    @classmethod
    def from_json(cls, text: str) -> Self:
        return cls.from_dict(json_object(text, ParamSetError,
                                         f"{cls._group} parameters are not valid JSON",
                                         f"{cls._group} parameters must be a JSON object"))

    def with_values(self, **values: Any) -> Self:
        """A copy with some parameters changed (validated)."""
        return self.from_dict({**self.to_dict(), **values})

    def diff(self, other: ParamSet) -> dict[str, tuple[Any, Any]]:
        """Parameters that differ: dotted name -> (self value, other value)."""
        a, b = self.to_dict(), other.to_dict()
        out = {}
        for k, va in a.items():
            vb = b.get(k)
            if not same_value(va, vb):
                out[f"{self._group}.{k}"] = (va, vb)
        return out
