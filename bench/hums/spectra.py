"""Current spectrum (thesis eq. 6.3) and the harmonic features read from it.

One-sided amplitude spectrum of a windowed rfft, calibrated so a sine of amplitude A
reads A at its line (`amplitude_spectrum`); harmonic features are the amplitudes of the
command frequency f0 and its multiples, each read from the energy of its main lobe so
they hold off-bin too (`harmonic_amplitudes`).
"""

from __future__ import annotations

import math

import numpy as np

from bench import BenchError

N_HARMONICS = 5


def _window(name: str, n: int) -> np.ndarray:
    """The DFT-even (periodic) window `name` of `n` samples: exact on-bin for the DFT."""
    from scipy.signal import get_window
    kind = {"hann": "hann", "hanning": "hann", "rect": "boxcar", "rectangular": "boxcar",
            "boxcar": "boxcar", "none": "boxcar", "flattop": "flattop"}.get(name)
    if kind is None:
        raise BenchError(f"unknown window {name!r} (hann, rect, flattop)")
    return get_window(kind, n, fftbins=True)


def amplitude_spectrum(y: np.ndarray, dt: float, window: str = "hann",
                       detrend: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum of `y` sampled every `dt` s (eq. 6.3, numpy rfft).

    Calibrated by the window's coherent gain: a sine of amplitude A whose frequency falls
    on a bin reads A at that bin (between bins, the Hann window reads down to 0.85 A at
    the peak; `harmonic_amplitudes` reads the lobe energy instead). With `detrend` the
    mean is removed first (it is reported by no bin). Returns (frequencies Hz, amplitudes
    in the unit of y).
    """
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or len(y) < 4:
        raise BenchError("a spectrum needs a 1-D signal of at least 4 samples")
    if not np.isfinite(y).all():
        raise BenchError("the signal has non-finite samples; cannot compute its spectrum")
    if detrend:
        y = y - y.mean()
    w = _window(window, len(y))
    spec = np.abs(np.fft.rfft(y * w)) / w.sum()
    spec[1:] *= 2.0
    if len(y) % 2 == 0:
        spec[-1] /= 2.0          # the Nyquist bin has no mirror
    return np.fft.rfftfreq(len(y), dt), spec


def harmonic_amplitudes(y: np.ndarray, dt: float, f0: float, n: int = N_HARMONICS,
                        window: str = "hann") -> np.ndarray:
    """Amplitudes of f0, 2 f0, ..., n f0 in `y` (unit of y), NaN above Nyquist.

    Each is sqrt(4 sum|X_k|^2 / (N sum w^2)) over the bins nearer h f0 than half the
    spacing of the harmonics (and within the window's main lobe, +-2 bins for Hann):
    Parseval's reading of a sine's amplitude, which does not depend on where the line
    falls between bins once the harmonics are at least 4 bins apart (a Hann window of at
    least four command periods, as the thesis' FFT; within one period use "rect").
    """
    y = np.asarray(y, dtype=float)
    if not (math.isfinite(f0) and f0 > 0):
        raise BenchError("harmonic amplitudes need a command frequency f0 > 0 Hz")
    if len(y) < 4 or not np.isfinite(y).all():
        raise BenchError("harmonic amplitudes need a finite signal of at least 4 samples")
    N = len(y)
    y = y - y.mean()
    w = _window(window, N)
    X = np.fft.rfft(y * w)
    df = 1.0 / (N * dt)
    bins_per_h = f0 / df
    lobe = {"hann": 2, "hanning": 2, "flattop": 5}.get(window, 1)
    if bins_per_h < 1.0 - 1e-9:
        raise BenchError(f"the window ({N * dt:.3g} s) is shorter than one period of "
                         f"{f0:g} Hz: no harmonic can be resolved")
    norm = N * float(np.sum(w * w))
    out = np.full(n, np.nan)
    k = np.arange(len(X))
    reach = min(lobe + 1.0, 0.5 * bins_per_h)   # each harmonic's own share of the bins
    for h in range(1, n + 1):
        c = h * bins_per_h
        if c + reach >= len(X) - 1:
            break
        sel = (np.abs(k - c) < reach) & (k >= 1)
        out[h - 1] = math.sqrt(4.0 * float(np.sum(np.abs(X[sel]) ** 2)) / norm)
    return out
