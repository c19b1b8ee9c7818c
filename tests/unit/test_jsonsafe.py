"""The one JSON encoding of reports (bench/core/jsonsafe.py)."""

from __future__ import annotations

import json
import math

import numpy as np

from bench.core.jsonsafe import json_safe


def test_non_finite_numbers_become_null_at_any_depth():
    v = {"a": math.nan, 3: [np.float64(math.inf), (1.5, np.int64(2))], "b": np.bool_(True),
         "c": {"d": -math.inf, "e": "text"}}
    out = json_safe(v)
    assert out == {"a": None, "3": [None, [1.5, 2]], "b": True, "c": {"d": None, "e": "text"}}
    assert type(out["3"][1][1]) is int and type(out["b"]) is bool
    json.dumps(out, allow_nan=False)          # strict JSON
