"""The bench's one verdict model: a `Level` and a `Verdict` every producer returns and
every report prints.

Levels (one vocabulary, one numeric encoding, the thesis' section 6.5 scale):

======== ==== ====================================================================
level    code meaning
======== ==== ====================================================================
UNKNOWN   -1  not judged: what it rests on is missing (the first reason says what)
HEALTHY    0  judged, nothing above its threshold
DEGRADED   1  a deviation no longer negligible (Ci below 0.93; a rig cycle or log
              outside its healthy baseline, a rig log outside its calibrated model)
WARNING    2  Ci below 0.80 or the fused backlash above its warning level (a rig
              baseline has no warning or failure level)
FAILURE    3  Ci below 0.56 or the fused backlash above its failure level
======== ==== ====================================================================

The code is the level's integer value (`int(level)`), stored as is (the fleet store's
``level`` column); `Level.parse` reads every form a level was ever stored in: the names,
the codes, NULL / NaN / an empty string (UNKNOWN), and 4 (UNKNOWN as an index past the
four judged levels).

A `Verdict` is a level with the effect it names (the index or signature that set it,
"none" when nothing is above, "not judged" when UNKNOWN), its reasons and the
reference it was judged against ("thesis model", "rig baseline ...", "calibration
...").
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, replace
from typing import Any


class Level(enum.IntEnum):
    """A verdict's level (module doc); its value is its one numeric code."""
    UNKNOWN = -1
    HEALTHY = 0
    DEGRADED = 1
    WARNING = 2
    FAILURE = 3

    def __str__(self) -> str:
        return self.name

    def __format__(self, spec: str) -> str:
        return format(self.name, spec)

    @classmethod
    def parse(cls, value: Any) -> Level:
        """The level `value` stands for: a `Level`, a name (any case), a code -1..3, or
        a stored form of UNKNOWN (None, NaN, "", 4). ValueError otherwise."""
        if isinstance(value, Level):
            return value
        if value is None:
            return cls.UNKNOWN
        if isinstance(value, str):
            text = value.strip().upper()
            if not text:
                return cls.UNKNOWN
            if text in cls.__members__:
                return cls[text]
            try:
                return cls.parse(int(text))
            except ValueError:
                raise ValueError(f"not a verdict level: {value!r}") from None
        if isinstance(value, bool):
            raise ValueError(f"not a verdict level: {value!r}")
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"not a verdict level: {value!r}") from None
        if math.isnan(number):
            return cls.UNKNOWN
        if number == 4:                      # UNKNOWN as the index after FAILURE
            return cls.UNKNOWN
        if number.is_integer() and -1 <= number <= 3:
            return cls(int(number))
        raise ValueError(f"not a verdict level: {value!r}")


@dataclass(frozen=True)
class Verdict:
    """A level, the effect that set it, the reasons and the reference (module doc)."""
    level: Level
    effect: str = "none"
    reasons: tuple[str, ...] = field(default_factory=tuple)
    reference: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "level", Level.parse(self.level))
        object.__setattr__(self, "reasons", tuple(self.reasons))

    @classmethod
    def unknown(cls, reasons: Any, reference: str = "") -> Verdict:
        """Not judged: `reasons` (the first says what is missing)."""
        return cls(Level.UNKNOWN, "not judged", tuple(reasons), reference)

    @property
    def name(self) -> str:
        """The level's name, as every report prints it."""
        return self.level.name

    @property
    def judged(self) -> bool:
        return self.level != Level.UNKNOWN

    @property
    def flagged(self) -> bool:
        """Judged and above HEALTHY."""
        return self.level > Level.HEALTHY

    def against(self, reference: str) -> Verdict:
        """The same verdict judged against `reference`."""
        return replace(self, reference=reference)

    def to_json(self) -> dict[str, Any]:
        """The one JSON shape of a verdict: level (name), code, effect, reasons,
        reference."""
        return {"level": self.level.name, "code": int(self.level), "effect": self.effect,
                "reasons": list(self.reasons), "reference": self.reference}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Verdict:
        """The verdict `to_json` wrote (the level read with `Level.parse`)."""
        return cls(Level.parse(data.get("level")), str(data.get("effect", "none")),
                   tuple(data.get("reasons") or ()), str(data.get("reference", "")))
