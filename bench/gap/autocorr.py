"""Correlation length of a residual series: how many samples make one independent one.

Residuals of a closed loop are not independent samples; the fit's information criteria
(`bench.gap.fit`) and the noise floors of the smoothed residuals (`bench.gap.problem`)
divide the sample count by this length. Kept here rather than taken from a library:
statsmodels' `acf` would do the autocorrelation, but not the integration up to its
first non-positive value, and it is not a dependency.
"""

from __future__ import annotations

import numpy as np


def corr_length(r: np.ndarray, max_lag: int = 400) -> float:
    """Integrated autocorrelation time of a residual series (samples, >= 1): 1 + 2 sum of
    the autocorrelation up to its first non-positive value."""
    r = np.asarray(r, float)
    r = r - r.mean()
    n = len(r)
    if n < 4 or not np.any(r):
        return 1.0
    m = min(max_lag, n // 4)
    f = np.fft.rfft(r, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[:m + 1]
    ac = ac / ac[0]
    s = 0.0
    for k in range(1, m + 1):
        if ac[k] <= 0.0:
            break
        s += ac[k]
    return float(max(1.0, 1.0 + 2.0 * s))


def long_run_cov(g: np.ndarray, lag: int) -> np.ndarray:
    """Long-run covariance of the score series `g` (n, k): sum over lags |l| <= `lag` of
    the Bartlett-weighted (1 - |l| / (lag + 1)) lagged products (Newey and West 1987):
    the variance of sum_t g_t when the g_t are correlated over a few `lag` samples."""
    g = np.asarray(g, float)
    out = g.T @ g
    for k in range(1, min(lag, len(g) - 1) + 1):
        c = g[k:].T @ g[:-k]
        out += (1.0 - k / (lag + 1.0)) * (c + c.T)
    return out
