"""The compiled kernels of the rig's cycle features give numpy's numbers bit for bit:
each against the numpy expression it replaces, on random arrays of every length that
matters (numpy's pairwise summation changes its pattern at 8 and 128 values), with
NaN, infinities and signed zeros."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.rig import kernels as K

SCALES = np.array((1, 3, 9, 27))


@pytest.fixture(scope="module", autouse=True)
def compiled():
    """Load (or compile) the kernels once, outside the tests' time (numba's disk cache)."""
    x = np.arange(10.0)
    K.psum(x), K.scan(x, SCALES), K.median(x), K.constant(x + 1, x, 0), K.nanargmax(x)
    K.absmax(x), K.ramp_bounds(x, 0.9)


def same(a: float, b: float) -> bool:
    """Equal bit for bit (any NaN equals any NaN; 0.0 and -0.0 differ)."""
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return np.float64(a).tobytes() == np.float64(b).tobytes()


def np_scan(z: np.ndarray) -> tuple[float, int, int]:
    """The numpy window scan the kernel replaces (as `features.scan` was)."""
    best = (0.0, 0, 1)
    zz = np.nan_to_num(z)
    c = np.r_[0.0, np.cumsum(zz)]
    for w in SCALES:
        if w > len(zz):
            break
        s = (c[w:] - c[:-w]) / math.sqrt(w)
        k = int(np.argmax(np.abs(s)))
        if abs(s[k]) > best[0]:
            best = (float(abs(s[k])), k + w // 2, int(w))
    return best


def arrays(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3, n)


LENGTHS = [*range(0, 140), 255, 256, 257, 300, 1000, 4097]


def test_psum_is_numpys_sum_bit_for_bit():
    rng = np.random.default_rng(0)
    for n in LENGTHS:
        for _ in range(5):
            x = arrays(rng, n)
            assert same(K.psum(x), np.sum(x)), n
            assert same(K.psum(x) / max(n, 1), np.mean(x) if n else 0.0), n
    assert same(K.psum(np.array([-0.0] * 9)), np.sum(np.array([-0.0] * 9)))


def test_scan_is_the_numpy_scan_bit_for_bit():
    rng = np.random.default_rng(1)
    for n in LENGTHS[:140:3] + [250, 300]:
        x = arrays(rng, n)
        got, want = K.scan(x, SCALES), np_scan(x)
        assert same(got[0], want[0]) and got[1:] == want[1:], n


def test_absmax_and_the_ramps_cut_are_numpys():
    from bench.rig.cycles import RAMP_FRACTION
    rng = np.random.default_rng(4)
    for n in range(2, 80):
        sp = np.cumsum(rng.uniform(0, 1, n) * (rng.uniform(0, 1, n) > 0.2))
        v = np.abs(np.gradient(sp))
        idx = np.flatnonzero(v >= RAMP_FRACTION * float(np.median(v)))
        want = (int(idx[0]), int(idx[-1]) + 1) if len(idx) else (0, n)
        assert tuple(K.ramp_bounds(sp, RAMP_FRACTION)) == want, n
        x = arrays(rng, n)
        assert same(K.absmax(x), np.max(np.abs(x)))
        x[n // 2] = np.nan
        assert math.isnan(K.absmax(x))


def test_median_and_nanargmax_are_numpys():
    rng = np.random.default_rng(2)
    for n in range(1, 60):
        x = arrays(rng, n)
        assert same(K.median(x), np.median(x)), n
        x[rng.integers(0, n)] = np.nan
        assert same(K.median(x), np.median(x)), n
        if np.isfinite(x).any():
            assert K.nanargmax(x) == np.nanargmax(x), n
    assert math.isnan(K.median(np.zeros(0)))


def np_constant(std, z, start=0):
    u = 1.0 / std[:len(z)]
    zz, uu = z[start:], u[start:]
    if not len(zz):
        zz, uu = z, u
    den = float(np.sum(uu * uu))
    return float(np.sum(zz * uu) / den), 1.0 / math.sqrt(den)


def test_constant_is_the_numpy_constant():
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 8, 9, 30, 125, 128, 129, 250):
        std = rng.uniform(0.01, 1.0, n + 3)
        z = arrays(rng, n)
        for start in (0, 1, n // 2, n):
            got, want = K.constant(std, z, start), np_constant(std, z, start)
            assert same(got[0], want[0]) and same(got[1], want[1]), (n, start)


special = st.sampled_from([0.0, -0.0, 1.0, -1.0, np.nan, np.inf, -np.inf, 1e308, -1e308,
                           5e-324])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                          special), max_size=60))
def test_scan_and_sum_on_any_values(values):
    """NaN, infinities, overflow and signed zeros: the same as numpy."""
    x = np.asarray(values, dtype=float)
    with np.errstate(all="ignore"):
        got, want = K.scan(x, SCALES), np_scan(x)
        assert same(got[0], want[0]) and got[1:] == want[1:]
        assert same(K.psum(x), np.sum(x))
        assert same(K.median(x), np.median(x)) if len(x) else True


@pytest.mark.parametrize("n", [0, 1, 5])
def test_scan_of_short_arrays(n):
    x = np.arange(n, dtype=float)
    assert K.scan(x, SCALES) == np_scan(x)
