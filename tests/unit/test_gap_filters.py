"""The gap's moving average, dilation and spectral window are scipy's and equal the
hand-written forms they replaced (edge-padded convolution, numpy's Hann)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import get_window

from bench.gap import localise as LZ
from bench.gap import problem as PR


def _padded_mean(y: np.ndarray, w: int) -> np.ndarray:
    return np.convolve(np.pad(y, (w // 2, w - 1 - w // 2), mode="edge"), np.ones(w) / w,
                       mode="valid")


@pytest.mark.parametrize("n", [10, 57, 4001])
@pytest.mark.parametrize("w", [2, 3, 9, 10])
def test_moving_average_is_the_edge_padded_mean(n, w):
    y = np.random.default_rng(n + w).standard_normal(n).cumsum()
    ref = _padded_mean(y, w)
    for got in (LZ._smooth(y, w), PR.smooth(y, w)):
        assert got.shape == y.shape
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * np.max(np.abs(y)))


def test_short_series_are_copied():
    y = np.arange(4.0)
    assert np.array_equal(LZ._smooth(y, 9), y) and np.array_equal(PR.smooth(y, 9), y)


@pytest.mark.parametrize("half", [1, 5, 50])
def test_dilation_is_the_convolution_test(half):
    m = np.random.default_rng(half).random(1000) > 0.98
    ref = np.convolve(m.astype(float), np.ones(2 * half + 1), mode="same") > 0.5
    assert np.array_equal(LZ._dilate(m, half), ref)


def test_hann_window_is_numpys():
    for n in (8, 9, 1000, 4001):
        np.testing.assert_allclose(get_window("hann", n, fftbins=False), np.hanning(n),
                                   rtol=0, atol=1e-15)
