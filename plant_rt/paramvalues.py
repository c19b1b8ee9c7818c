"""Parameter values read from JSON and compared: what the plant's `PlantParams` and the
bench's parameter sets (`bench.core.paramset`) do alike."""

from __future__ import annotations

import json
import math
from typing import Any


def same_value(a: Any, b: Any) -> bool:
    """Whether two parameter values are the same (a NaN, "not set", is the same as a NaN)."""
    return a == b or (isinstance(a, float) and isinstance(b, float)
                      and math.isnan(a) and math.isnan(b))


def json_object(text: str, error: type[Exception], not_json: str, not_object: str
                ) -> dict[str, Any]:
    """The JSON object in `text`; else `error` with `not_json` (and the decoder's reason)
    or with `not_object`."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{not_json}: {exc}") from None
    if not isinstance(data, dict):
        raise error(not_object)
    return data


SEED_MAX = 2**31 - 1
"""The largest seed a seed parameter takes (an INTEGER32 object on the bus, dbc/ema.eds)."""


def seed_in_range(seed: int) -> int:
    """A seed derived from a user's seed (``seed * 1_000_003 + k``), folded into the
    seed parameters' range: unchanged where it already lies in [0, SEED_MAX)."""
    return int(seed) % SEED_MAX
