"""The HUMS indexes of chapter 6 as a distance of a log from a model (gap "as the HUMS
sees it"), computed by `bench.hums.indexes`.

With x the logged nut position (m), i the logged current (A) and x_N, i_N the model's
(the ratio-of-integrals reading of eq. 6.4-6.7, docs/hums.md):
    Cp = int(x_N x) / int(x^2)    Ci = int(i_N i) / int(i^2)
    peak ratio = max|i| / max|i_N|      mean error = mean |x - x_N|  (m)
Each is 1 (0 for the mean error) when log and model agree.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.hums import indexes as H


def indexes(meas: dict[str, np.ndarray], sim: dict[str, np.ndarray], lo: int, hi: int,
            dt: float) -> dict[str, Any]:
    """Indexes of `meas` against `sim` over samples [lo, hi) and their distances."""
    x, xn = meas["position_m"][lo:hi], sim["position_m"][lo:hi]
    i, i_n = meas["current_a"][lo:hi], sim["current_a"][lo:hi]
    got = {"cp": float(H.cp(xn, x)), "ci": float(H.ci(i_n, i)),           # eq. 6.5, 6.6
           "peak_ratio": float(H.peak_ratio(i_n, i)),                      # eq. 6.7
           "mean_error_m": float(H.mean_error(xn, x))}                     # eq. 6.4
    dist = {"cp": abs(got["cp"] - 1.0), "ci": abs(got["ci"] - 1.0),
            "peak_ratio": abs(got["peak_ratio"] - 1.0), "mean_error_m": got["mean_error_m"]}
    return {"values": got, "distance": dist, "source": "bench.hums.indexes"}
