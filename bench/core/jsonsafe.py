"""One JSON encoding of results for every report: non-finite numbers become null (JSON has
no NaN or inf), numpy scalars Python numbers, tuples lists, mapping keys strings."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def json_safe(v: Any) -> Any:
    """`v` with every non-finite float replaced by None, recursively (dicts, lists,
    tuples), numpy scalars as Python scalars."""
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.floating | np.integer):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {str(k): json_safe(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [json_safe(x) for x in v]
    return v
