"""A trace whose signal holds a value beyond any measurement (1e308 m) was graded
("FAILURE; Ci = -0.002" after overflow warnings); it is refused when read, as an inf is."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.signals.trace import Trace


def test_a_value_beyond_any_measurement_is_refused_when_read(tmp_path):
    t = np.arange(10) * 1e-3
    path = Trace({"t_s": t, "position_m": np.full(10, 1e308)}, {}).save(tmp_path / "x.npz")
    with pytest.raises(BenchError, match="beyond any measurement"):
        Trace.load(path)
    ok = Trace({"t_s": t, "position_m": np.full(10, 0.05)}, {}).save(tmp_path / "y.npz")
    assert Trace.load(ok)["position_m"][0] == 0.05
