"""The HUMS indexes of chapter 6 as a distance of a log from a model (gap "as the HUMS
sees it").

With x the logged nut position (m), i the logged current (A) and x_N, i_N the model's
(design.md's reading of eq. 6.5-6.6, ratio of integrals):
    Cp = int(x_N x) / int(x^2)    Ci = int(i_N i) / int(i^2)
    peak ratio = max|i| / max|i_N|      mean error = mean |x - x_N|  (m)
Each is 1 (0 for the mean error) when log and model agree. `bench.hums.indexes` (issue 4)
is used when it offers ``cp``, ``ci``, ``peak_ratio`` and ``mean_error`` taking
``(nominal, real)`` arrays; otherwise these formulas are computed here.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def _local(xn: np.ndarray, x: np.ndarray, i_n: np.ndarray, i: np.ndarray) -> dict[str, float]:
    def ratio(a: np.ndarray, b: np.ndarray) -> float:
        den = float(np.sum(b * b))
        return float(np.sum(a * b) / den) if den > 0 else float("nan")
    pk = float(np.max(np.abs(i_n)))
    return {"cp": ratio(xn, x), "ci": ratio(i_n, i),
            "peak_ratio": float(np.max(np.abs(i)) / pk) if pk > 0 else float("nan"),
            "mean_error_m": float(np.mean(np.abs(x - xn)))}


def _hums(xn: np.ndarray, x: np.ndarray, i_n: np.ndarray, i: np.ndarray
          ) -> dict[str, float] | None:
    try:
        from bench.hums import indexes as H  # type: ignore[attr-defined]
    except ImportError:
        return None
    try:
        return {"cp": float(H.cp(xn, x)), "ci": float(H.ci(i_n, i)),
                "peak_ratio": float(H.peak_ratio(i_n, i)),
                "mean_error_m": float(H.mean_error(xn, x))}
    except (AttributeError, TypeError, ValueError):
        return None


def indexes(meas: dict[str, np.ndarray], sim: dict[str, np.ndarray], lo: int, hi: int,
            dt: float) -> dict[str, Any]:
    """Indexes of `meas` against `sim` over samples [lo, hi) and their distances."""
    x, xn = meas["position_m"][lo:hi], sim["position_m"][lo:hi]
    i, i_n = meas["current_a"][lo:hi], sim["current_a"][lo:hi]
    got = _hums(xn, x, i_n, i)
    src = "bench.hums.indexes"
    if got is None:
        got = _local(xn, x, i_n, i)
        src = "bench.gap.indexes (design.md reading; bench.hums.indexes not available)"
    dist = {"cp": abs(got["cp"] - 1.0), "ci": abs(got["ci"] - 1.0),
            "peak_ratio": abs(got["peak_ratio"] - 1.0), "mean_error_m": got["mean_error_m"]}
    return {"values": got, "distance": dist, "source": src}
