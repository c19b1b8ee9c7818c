"""Compiled kernels of the cycle features (`features`): the same arithmetic as the numpy
expressions they replace, in the same order, so every score is bit for bit the one numpy
gives, at a fraction of the cost on a cycle's short arrays (a stroke is about 125
samples, where numpy's per-call overhead is most of the time).

- `psum` is numpy's pairwise summation of a float64 array (`np.sum`, `np.mean` divide
  it by the count): blocks of up to 128 values summed in 8 interleaved partial sums,
  longer arrays halved (at multiples of 8) and the halves added, the identity 0.0 added
  last.
- `scan` is `features.scan`'s window search: `np.nan_to_num`, the cumulative sum with a
  leading 0, and per scale the first largest |window sum / sqrt(width)| (np.argmax's
  first index; a NaN is the largest, as np.argmax takes it).
- `median` is `np.median` of a 1-D array (NaN when any value is NaN or the array is
  empty; the mean of the two middle values of an even count, as `np.mean` of them).
- `constant` is `features.constant`'s weighted least-squares constant.
- `nanargmax` is `np.nanargmax` (NaN as -inf, first index of the largest; the caller
  makes sure a finite value exists); `absmax` is `np.max(np.abs(a))`.
- `ramp_bounds` is `cycles.ramps`' cut of a stroke (`np.gradient` of the set-point, its
  median, the first and last sample at full speed).

tests/unit/test_rig_kernels.py checks each one against its numpy expression, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from plant_rt.jit import njit

_BIG = 1.7976931348623157e308      # np.nan_to_num's replacement of +inf (float64 max)


@njit(cache=True)
def _block(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a[lo:lo + n] for n <= 128 (its unrolled leaf)."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    m = n - n % 8
    while i < m:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def _pairwise(a: np.ndarray) -> float:
    """numpy's pairwise sum of `a`: leaves of up to 128 values, a longer part halved at a
    multiple of 8 and its halves' sums added (the recursion unrolled on a stack: numba
    does not reload a recursive function from its disk cache safely)."""
    n = len(a)
    if n <= 128:
        return _block(a, 0, n)
    los = np.empty(128, dtype=np.int64)
    ns = np.empty(128, dtype=np.int64)
    done = np.zeros(128, dtype=np.bool_)
    vals = np.empty(128)
    sp, vp = 1, 0
    los[0], ns[0] = 0, n
    while sp:
        t = sp - 1
        lo, m = los[t], ns[t]
        if m <= 128:
            vals[vp] = _block(a, lo, m)
            vp += 1
            sp -= 1
        elif done[t]:
            vals[vp - 2] = vals[vp - 2] + vals[vp - 1]
            vp -= 1
            sp -= 1
        else:
            done[t] = True
            m2 = m // 2
            m2 -= m2 % 8
            los[sp], ns[sp], done[sp] = lo + m2, m - m2, False       # right, summed second
            los[sp + 1], ns[sp + 1], done[sp + 1] = lo, m2, False    # left, summed first
            sp += 2
    return vals[0]


@njit(cache=True)
def psum(a: np.ndarray) -> float:
    """`np.sum(a)` of a 1-D float64 array, bit for bit."""
    return 0.0 + _pairwise(a)


@njit(cache=True)
def scan(z: np.ndarray, scales: np.ndarray) -> tuple[float, int, int]:
    """`features.scan`: (score, centre index, width)."""
    n = len(z)
    c = np.empty(n + 1)
    c[0] = 0.0
    acc = 0.0
    for i in range(n):
        v = z[i]
        if math.isnan(v):
            v = 0.0
        elif v == math.inf:
            v = _BIG
        elif v == -math.inf:
            v = -_BIG
        acc = v if i == 0 else acc + v
        c[i + 1] = acc
    best, centre, width = 0.0, 0, 1
    for w in scales:
        if w > n:
            break
        sq = math.sqrt(w)
        k = 0
        mp = abs((c[w] - c[0]) / sq)
        if not math.isnan(mp):
            for i in range(1, n - w + 1):
                v = abs((c[i + w] - c[i]) / sq)
                if math.isnan(v):
                    k = i
                    mp = v
                    break
                if v > mp:
                    mp = v
                    k = i
        if mp > best:
            best, centre, width = mp, k + w // 2, w
    return best, centre, width


@njit(cache=True)
def median(a: np.ndarray) -> float:
    """`np.median(a)` of a 1-D float64 array."""
    n = len(a)
    if n == 0:
        return math.nan
    s = np.sort(a)
    if math.isnan(s[n - 1]):
        return math.nan
    h = n // 2
    if n % 2:
        return 0.0 + (-0.0 + s[h])
    return (0.0 + ((-0.0 + s[h - 1]) + s[h])) / 2.0


@njit(cache=True)
def constant(std: np.ndarray, z: np.ndarray, start: int) -> tuple[float, float]:
    """`features.constant`: (constant, its standard error)."""
    n = len(z)
    u = 1.0 / std[:n]
    zz, uu = z[start:], u[start:]
    if len(zz) == 0:
        zz, uu = z, u
    den = psum(uu * uu)
    return psum(zz * uu) / den, 1.0 / math.sqrt(den)


@njit(cache=True)
def nanargmax(a: np.ndarray) -> int:
    """`np.nanargmax(a)` of an array with a finite value."""
    k = 0
    mp = -math.inf if math.isnan(a[0]) else a[0]
    for i in range(1, len(a)):
        v = a[i]
        if not math.isnan(v) and v > mp:
            mp = v
            k = i
    return k


@njit(cache=True)
def absmax(a: np.ndarray) -> float:
    """`np.max(np.abs(a))` of a non-empty 1-D array (NaN when any value is NaN)."""
    m = abs(a[0])
    if math.isnan(m):
        return m
    for i in range(1, len(a)):
        v = abs(a[i])
        if math.isnan(v):
            return v
        if v > m:
            m = v
    return m


@njit(cache=True)
def ramp_bounds(sp: np.ndarray, frac: float) -> tuple[int, int]:
    """`cycles.ramps` of a stroke's set-point `sp` (two or more samples): the first and
    one past the last sample whose |np.gradient| is at least `frac` of its median, (0,
    len(sp)) when none is."""
    n = len(sp)
    v = np.empty(n)
    v[0] = abs(sp[1] - sp[0])
    for i in range(1, n - 1):
        v[i] = abs((sp[i + 1] - sp[i - 1]) / 2.0)
    v[n - 1] = abs(sp[n - 1] - sp[n - 2])
    thr = frac * median(v)
    a, b = -1, -1
    for i in range(n):
        if v[i] >= thr:
            if a < 0:
                a = i
            b = i + 1
    if a < 0:
        return 0, n
    return a, b
