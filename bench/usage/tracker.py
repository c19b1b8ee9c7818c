"""Motion with a hysteresis, one sample at a time and resumable (a log in one go, the
live watcher row by row give the same numbers).

`Tracker` follows a signal x with a band of width h:

- the play (backlash) operator y = min(max(y, x - h/2), x + h/2): its increments are the
  motion that counts (revolutions, travel); oscillations smaller than h move it not at
  all, and each reversal costs h of travel;
- the turning points: the extreme of x is kept until x has retreated from it by h, then
  recorded as a turning point (a reversal) and the search turns around. These are the
  peaks and valleys that rainflow counting (ASTM E1049) takes, with ranges below h
  filtered out (a range filter, the usual step before counting). The first sample
  is the first point; the pending extreme is the last one.

NaN samples are skipped. The loop is compiled (numba): a 1 kHz log of an hour is 3.6
million samples.
"""

from __future__ import annotations

import math

import numpy as np

from plant_rt.jit import njit

# state vector: y (play output), ext (pending extreme), direction (+1, -1, 0: none yet),
# lo, hi (range seen before the first direction), started (0/1)
_Y, _EXT, _DIR, _LO, _HI, _STARTED = range(6)


@njit(cache=True)
def _first_direction(v, st, h):  # pragma: no cover - compiled
    """Before the first move: widen the range seen; set the direction once it spans h (up
    if the top came last; the other end, within h of the first sample, is filtered)."""
    if v > st[_HI]:
        st[_HI] = v
    if v < st[_LO]:
        st[_LO] = v
    if st[_HI] - st[_LO] >= h and st[_HI] > st[_LO]:
        st[_DIR] = 1.0 if v == st[_HI] else -1.0
        st[_EXT] = v


@njit(cache=True)
def _turned(v, st, h):  # pragma: no cover - compiled
    """True (and the search turned around) when v retreated h from the pending extreme."""
    back = (st[_EXT] - v) * st[_DIR]     # how far v is behind the extreme
    if back < 0.0:
        st[_EXT] = v
        return False
    if back >= h and back > 0.0:
        st[_DIR] = -st[_DIR]
        return True
    return False


@njit(cache=True)
def _track(x, h, st, dy, tp):  # pragma: no cover - compiled
    """Advance state `st` over samples `x`: play increments into `dy`, new turning points
    into `tp`; returns the number of turning points written."""
    n_tp = 0
    half = 0.5 * h
    for k in range(x.shape[0]):
        v = x[k]
        dy[k] = 0.0
        if not math.isfinite(v):
            continue
        if st[_STARTED] == 0.0:
            st[_STARTED] = 1.0
            st[_Y] = v
            st[_LO] = v
            st[_HI] = v
            tp[n_tp] = v
            n_tp += 1
            continue
        y = st[_Y]
        ny = min(max(y, v - half), v + half)
        dy[k] = ny - y
        st[_Y] = ny
        if st[_DIR] == 0.0:
            _first_direction(v, st, h)
            continue
        ext = st[_EXT]
        if _turned(v, st, h):
            tp[n_tp] = ext
            n_tp += 1
            st[_EXT] = v
    return n_tp


class Tracker:
    """A signal followed with hysteresis `h` (module docstring); feed it with `push`."""

    def __init__(self, h: float) -> None:
        self.h = float(h)
        self.state = np.zeros(6)
        self.points: list[float] = []      # turning points so far (the first sample first)
        self.travel = 0.0                  # sum of |play increments|

    def push(self, x: np.ndarray) -> np.ndarray:
        """Samples `x` in; their play increments out (0 for NaN samples)."""
        x = np.ascontiguousarray(x, dtype=float)
        dy = np.empty_like(x)
        tp = np.empty(len(x) + 1)
        n = _track(x, self.h, self.state, dy, tp)
        self.points.extend(tp[:n].tolist())
        self.travel += float(np.abs(dy).sum())
        return dy

    @property
    def reversals(self) -> int:
        """Turning points between the first sample and the pending extreme."""
        return max(len(self.points) - 1, 0)

    def series(self) -> np.ndarray:
        """The turning points and the pending extreme: the series to count cycles on."""
        if not self.state[_STARTED]:
            return np.zeros(0)
        pts = list(self.points)
        if self.state[_DIR] != 0.0:
            pts.append(float(self.state[_EXT]))
        return np.array(pts)
