"""Prognosis from a rig's own trend: its own index, its own units, real days.

`prognose(trend, settings)` runs, test after test, on one actuator's index (each
estimate uses only the tests up to its own, as if the command ran on that day):

1. **Healthy reference**: the first N tests (`--healthy-tests N`, default
   `DEFAULT_HEALTHY`) or those up to a date: the healthy level h0 (their mean) and the
   noise (their sd; later the larger of it and the scatter of the trend's second
   differences over the last `NOISE_WINDOW` tests, which a slow trend does not inflate).
2. **Detection**: a one-sided CUSUM (Page 1954; k = 0.5, h = `CUSUM_H`) of the tests'
   deviations from healthy in noise sd, less twice the healthy mean's standard error (a
   reference of few tests is itself uncertain), each a normal score under the noise's
   Student-t and capped at `Z_CLIP` (one test alone never detects). It gives the day of
   the detection and the day the change began (the CUSUM's last zero).
3. **Threshold**: the failure level the user states (`--failure 4.6`, in the index's
   unit, or `--failure 2x` the healthy level), an optional warning level. Without one
   there is no RUL: the detection only, and a note that a RUL needs a threshold. A level
   must be finite and within +-`MAX_VALUE` (the trend reader's limit on a value), and
   the failure level within `MAX_SPAN_SD` healthy sd of the healthy level: the model
   works in units of that distance, and beyond it the healthy noise in those units is
   too small for its arithmetic (the posterior's precision matrix turns singular).
4. **Degradation model**: `bench.hums.trend_model`, a steady drift plus an exponential
   wear-out from a change time, its exact posterior on a grid, the healthy tests its
   first observations and their noise its prior; a test far from the best curve is "the
   trend left the model's range".
5. **RUL**: percentiles of the posterior's times to the threshold, in the file's time
   unit, from the detection on, with the notes that say when a band cannot be trusted.
6. **Peers on the same tests**: a plain z-score (3 sd of the healthy tests) alarm, and
   an exponential fitted to the index (log-linear least squares on every test so far)
   extrapolated to the threshold: the day it crosses, as of each test, and its alarm
   (the first test at which the crossing comes within one test interval).

Warning (each estimate's ``warning``): the filtered level past the warning level when one
is given, else the detection.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np
from scipy.special import ndtri, stdtr

from bench import BenchError
from bench.hums.trend_io import MAX_VALUE, Trend
from bench.hums.trend_model import (
    HORIZON,
    LOCAL_MIN,
    P_LOCAL,
    CurvePosterior,
    local_drift,
    samples,
)

DEFAULT_HEALTHY = 5
CUSUM_K = 0.5
CUSUM_H = 5.0
Z_CLIP = 4.0
Z_PEER = 3.0
NOISE_WINDOW = 60
WIDE = 2.0              # posterior noise over the healthy noise: said
FIT_Z = 4.5             # a test this many sd from the posterior's curve: out of range
PCT = (5, 25, 50, 75, 95)
BIG = 1e300
MAX_SPAN_SD = 1e4       # failure level at most this many healthy sd from healthy
COLUMNS = ("t", "value", "level_p5", "level_p50", "level_p95",
           *(f"rul_p{q}" for q in PCT), "toe_p50", "warning", "detected", "z_alarm",
           "exp_cross_t", "noise", "rul_open")
_LEVEL = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(x|X|[^\s\d].*)?\s*$")


@dataclass
class Settings:
    """What the user states (CLI options of `bench hums prognose` on its own trend)."""
    healthy: str | None = None       # "N" tests or a date; None: DEFAULT_HEALTHY tests
    failure: str | None = None       # "4.6", "4.6 A", "2x"
    warning: str | None = None
    decreasing: bool = False
    unit: str | None = None
    time_unit: str = "days"
    seed: int = 0
    keep_samples: int = 0            # RUL samples kept per test (TrendResult.samples)


@dataclass
class Reference:
    """The healthy reference: tests used, level, sd, the time of its last test."""
    n: int
    requested: str
    level: float
    sd: float
    t_end: float
    dt: float                        # median interval between its tests (time unit)


@dataclass
class TrendResult:
    """One actuator's prognosis: a row per test (`cols`), notes per test, events."""
    trend: Trend
    unit: str
    direction: int
    ref: Reference | None
    failure: float | None
    warning_level: float | None
    cols: dict[str, np.ndarray]
    notes_at: dict[int, list[str]] = field(default_factory=dict)
    events: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    samples: dict[int, np.ndarray] = field(default_factory=dict)

    def estimate(self, k: int) -> dict[str, Any]:
        """Test k's estimate (JSON shape: t, warning, rul_p5, rul_p50, rul_p95, ...)."""
        out: dict[str, Any] = {}
        for c in COLUMNS:
            v = float(self.cols[c][k])
            if c in ("warning", "detected", "z_alarm", "rul_open"):
                out[c] = bool(v)
            else:
                out[c] = v if math.isfinite(v) else None
        if self.trend.t0 is not None:
            out["date"] = self.trend.date(float(self.cols["t"][k]))
        out["notes"] = self.notes_at.get(k, [])
        return out


def parse_level(text: str, what: str, healthy: float, unit: str) -> float:
    """A level as the user states it: a number in the index's unit (an optional unit
    after it must be the index's) or a multiple of the healthy level ("2x")."""
    m = _LEVEL.match(text or "")
    if not m:
        raise BenchError(f"{what} {text!r}: give a level in the index's unit (4.6) or a "
                         "multiple of the healthy level (2x)")
    v, suffix = float(m.group(1)), (m.group(2) or "").strip()
    if not math.isfinite(v):
        raise BenchError(f"{what} {text!r} is not finite")
    if suffix.lower() == "x":
        if healthy == 0:
            raise BenchError(f"{what} {text}: a multiple of a healthy level of 0 is 0; give "
                             "the level in the index's unit")
        v *= healthy
    elif suffix and suffix != unit:
        raise BenchError(f"{what} {text!r}: the unit {suffix!r} does not match the index's "
                         f"unit {unit or '(none given)'!r}")
    if not abs(v) <= MAX_VALUE:
        raise BenchError(f"{what} {text!r} ({v:.4g}) is beyond +-{MAX_VALUE:g}, the "
                         "largest magnitude a trends file's value may have")
    return v


def _reference(tr: Trend, s: Settings) -> tuple[int, str]:
    """Number of healthy tests the settings ask for, and how they asked."""
    if s.healthy is None:
        return DEFAULT_HEALTHY, f"the first {DEFAULT_HEALTHY} tests (default; --healthy-tests)"
    text = s.healthy.strip()
    if re.fullmatch(r"\d+", text):
        n = int(text)
        if n < 2:
            raise BenchError(f"--healthy-tests {n}: a healthy spread needs at least 2 tests "
                             "(3 or more advised)")
        return n, f"the first {n} tests"
    if tr.t0 is None:
        raise BenchError(f"--healthy-tests {text!r}: a number of tests (the file's times "
                         "are numbers, not dates)")
    try:
        d = datetime.fromisoformat(text)
    except ValueError:
        raise BenchError(f"--healthy-tests {text!r}: a number of tests or an ISO date"
                         ) from None
    if (d.tzinfo is None) != (tr.t0.tzinfo is None):
        raise BenchError(f"--healthy-tests {text!r}: give the date with a time zone as the "
                         "file does, or without as the file does")
    until = (d - tr.t0).total_seconds() / 86400.0
    n = int(np.searchsorted(tr.t, until, side="right"))
    if n < 2:
        raise BenchError(f"--healthy-tests {text}: {n} test(s) up to that date; a healthy "
                         "spread needs at least 2")
    return n, f"the {n} tests up to {text}"


def _noise(y: np.ndarray, k: int, ref: Reference) -> tuple[float, float]:
    """Noise of one test and its degrees of freedom: the healthy sd (N - 1), or the
    trend's own scatter (second differences over the last NOISE_WINDOW tests, their
    median's efficiency ~0.6) when that is larger."""
    lo = max(0, k + 1 - NOISE_WINDOW)
    seg = y[lo:k + 1]
    own = 0.0
    if len(seg) >= 6:
        d2 = np.abs(seg[2:] - 2.0 * seg[1:-1] + seg[:-2])
        h = len(d2) // 2
        part = np.partition(d2, (h - 1, h) if len(d2) % 2 == 0 else h)
        med = 0.5 * (part[h - 1] + part[h]) if len(d2) % 2 == 0 else part[h]
        own = float(med) / 0.6745 / math.sqrt(6.0)
    if own > ref.sd:
        return own, max(2.0, 0.6 * (len(seg) - 2))
    return ref.sd, float(ref.n - 1)


def _quantiles(x: np.ndarray, pct: tuple[int, ...]) -> np.ndarray:
    """Percentiles of `x` (linear interpolation, as numpy's default), from one sort."""
    xs = np.sort(x)
    pos = np.asarray(pct, dtype=float) / 100.0 * (len(xs) - 1)
    lo = np.floor(pos).astype(int)
    hi = np.minimum(lo + 1, len(xs) - 1)
    return xs[lo] + (pos - lo) * (xs[hi] - xs[lo])


class _Peers:
    """The plain z-score and the exponential extrapolation, test by test (running sums of
    the log-linear fit)."""

    def __init__(self, ref: Reference, direction: int, failure: float | None) -> None:
        self.ref, self.s, self.failure = ref, direction, failure
        self.sums = np.zeros(5)            # n, t, t^2, ln y, t ln y
        self.positive = True

    def z_alarm(self, y: float) -> bool:
        return self.s * (y - self.ref.level) > Z_PEER * self.ref.sd

    def cross(self, t: float, y: float) -> float:
        """The day an exponential fitted to every test so far reaches the threshold."""
        if y <= 0:
            self.positive = False
        if not self.positive or self.failure is None or self.failure <= 0:
            return math.nan
        ly = math.log(y)
        self.sums += (1.0, t, t * t, ly, t * ly)
        n, st, stt, sl, stl = self.sums
        den = n * stt - st * st
        if n < 3 or den <= 0:
            return math.nan
        b = (n * stl - st * sl) / den
        a = (sl - b * st) / n
        if b == 0 or self.s * b <= 0:
            return math.inf
        tc = (math.log(self.failure) - a) / b
        return max(tc, t) if math.isfinite(tc) else math.inf


def _unit(tr: Trend, s: Settings) -> str:
    if s.unit and tr.unit and s.unit != tr.unit:
        raise BenchError(f"--unit {s.unit!r} does not match the unit {tr.unit!r} the file "
                         f"gives for {tr.index!r}")
    return tr.unit or s.unit or ""


def _levels(tr: Trend, s: Settings, ref: Reference, unit: str
            ) -> tuple[int, float | None, float | None]:
    """Direction of wear, failure and warning levels (checked against the reference)."""
    sign = -1 if s.decreasing else 1
    u = f" {unit}" if unit else ""
    who = f"actuator {tr.actuator!r}: " if tr.actuator else ""
    out: list[float | None] = []
    for flag, text in (("--failure", s.failure), ("--warning", s.warning)):
        if text is None:
            out.append(None)
            continue
        v = parse_level(text, flag, ref.level, unit)
        side = sign * (v - ref.level)
        how = f"the healthy level {ref.level:.4g}{u} (mean of {ref.requested})"
        if side <= 0:
            word, fix = (("below", "give --decreasing for an index that falls as it wears")
                         if sign > 0 else ("above", "drop --decreasing for an index that "
                                           "rises as it wears"))
            raise BenchError(f"{who}{flag} {text} ({v:.4g}{u}) is {word} {how}: {fix}")
        if side < 3.0 * ref.sd:
            raise BenchError(f"{who}{flag} {text} ({v:.4g}{u}) is within the healthy "
                             f"scatter ({how}, 3 sd = {3 * ref.sd:.3g}{u})")
        if flag == "--failure" and side > MAX_SPAN_SD * ref.sd:
            raise BenchError(f"{who}{flag} {text} ({v:.4g}{u}) is {side / ref.sd:.3g} "
                             f"healthy sd ({ref.sd:.3g}{u}) from {how}: the degradation "
                             f"model takes a failure level up to {MAX_SPAN_SD:g} sd away; "
                             "give a nearer level")
        out.append(v)
    fail, warn = out
    if fail is not None and warn is not None and sign * (warn - fail) >= 0:
        raise BenchError(f"{who}--warning {s.warning} is not before --failure {s.failure}")
    return sign, fail, warn


def make_reference(tr: Trend, s: Settings) -> Reference | None:
    """The healthy reference, or None while the file has fewer tests than it needs."""
    n, how = _reference(tr, s)
    if len(tr.t) < n:
        return None
    y = tr.y[:n]
    sd = float(np.std(y, ddof=1))
    if not sd > 0:
        raise BenchError(f"actuator {tr.actuator!r}: the {n} healthy tests of "
                         f"{tr.index!r} all read {y[0]:g}: no spread to set the noise by "
                         "(give more healthy tests)")
    return Reference(n, how, float(np.mean(y)), sd, float(tr.t[n - 1]),
                     float(np.median(np.diff(tr.t[:n]))))


def check(tr: Trend, s: Settings) -> None:
    """The settings against one trend, before any work: unit, healthy tests, levels
    (BenchError in one line when they cannot hold)."""
    unit = _unit(tr, s)
    ref = make_reference(tr, s)
    if ref is not None:
        _levels(tr, s, ref, unit)


def prognose(tr: Trend, s: Settings) -> TrendResult:
    """The prognosis of one trend, test by test (module docstring)."""
    unit = _unit(tr, s)
    n = len(tr.t)
    cols = {c: np.full(n, math.nan) for c in COLUMNS}
    cols["t"], cols["value"] = tr.t.copy(), tr.y.copy()
    for c in ("warning", "detected", "z_alarm", "rul_open"):
        cols[c] = np.zeros(n)
    ref = make_reference(tr, s)
    if ref is None:
        n_ref = _reference(tr, s)[0]
        res = TrendResult(tr, unit, -1 if s.decreasing else 1, None, None, None, cols)
        note = (f"healthy reference incomplete: {n} of {n_ref} tests so far; no "
                "detection and no RUL before it is complete")
        res.notes_at = {k: [note] for k in range(n)}
        res.notes.append(note)
        return res
    sign, fail, warn = _levels(tr, s, ref, unit)
    res = TrendResult(tr, unit, sign, ref, fail, warn, cols)
    _Run(res, s).run()
    return res


class _Run:
    """The test-by-test loop of `prognose` over one trend."""

    def __init__(self, res: TrendResult, s: Settings) -> None:
        self.res, self.s = res, s
        ref = res.ref
        assert ref is not None
        self.ref = ref
        self.tr = res.trend
        self.sign = res.direction
        self.span = (None if res.failure is None
                     else self.sign * (res.failure - ref.level))      # F - h0 toward wear
        self.rng = np.random.default_rng(s.seed)
        self.curve = CurvePosterior(ref.dt) if self.span is not None else None
        self.peers = _Peers(ref, self.sign, res.failure)
        self.cusum = 0.0
        self.last_zero = ref.n - 1
        self.unfit_since = math.nan        # day the trend left the model's range
        self.fit_run = 0                   # tests that fitted since
        self.texts: dict[str, str] = {}

    def run(self) -> None:
        tr, ref = self.tr, self.ref
        n_ref = ref.n
        pre = (f"healthy reference incomplete ({n_ref} tests: {ref.requested}); no "
               "detection and no RUL before it is complete")
        for k in range(n_ref - 1):
            self.res.notes_at[k] = [pre]
        for k in range(len(tr.t)):
            noise, dof = _noise(tr.y, k, ref)
            self.res.cols["noise"][k] = noise
            if k == n_ref - 1 and self.curve is not None:
                for j in range(n_ref):
                    self.curve.add(float(tr.t[j]), self._z(j))
            elif k >= n_ref and self.curve is not None:
                self.curve.add(float(tr.t[k]), self._z(k))
            if k >= n_ref:
                self._detect(k, noise, dof)
            if k >= n_ref - 1:
                self._estimate(k)
        self._summary()

    def _z(self, k: int) -> float:
        """Test k's degradation level u (0 healthy, 1 the failure threshold)."""
        assert self.span is not None
        return self.sign * (float(self.tr.y[k]) - self.ref.level) / self.span

    def _detect(self, k: int, noise: float, dof: float) -> None:
        ref, y = self.ref, float(self.tr.y[k])
        z = (self.sign * (y - ref.level) - 2.0 * ref.sd / math.sqrt(ref.n)) / noise
        # the deviation as a normal score under the noise's Student-t, clipped: one test
        # alone cannot make the detection
        z = min(float(ndtri(np.clip(stdtr(dof, z), 1e-12, 1 - 1e-12))), Z_CLIP)
        self.cusum = max(0.0, self.cusum + z - CUSUM_K)
        ev = self.res.events
        if self.cusum == 0.0:
            self.last_zero = k
        if self.cusum > CUSUM_H and "detected_t" not in ev:
            ev["detected_t"] = float(self.tr.t[k])
            ev["change_t"] = float(self.tr.t[min(self.last_zero + 1, k)])
        if self.peers.z_alarm(y) and "z_alarm_t" not in ev:
            ev["z_alarm_t"] = float(self.tr.t[k])

    def _note(self, k: int, text: str) -> None:
        text = self.texts.setdefault(text, text)        # one object per distinct note
        self.res.notes_at.setdefault(k, []).append(text)

    def _estimate(self, k: int) -> None:
        cols, ev, tr = self.res.cols, self.res.events, self.tr
        t, y = float(tr.t[k]), float(tr.y[k])
        cols["detected"][k] = float("detected_t" in ev)
        cols["z_alarm"][k] = float("z_alarm_t" in ev)
        cross = self.peers.cross(t, y)
        cols["exp_cross_t"][k] = cross
        if cross <= t + self.ref.dt and "exp_alarm_t" not in ev:
            ev["exp_alarm_t"] = t
        if self.span is None:
            cols["warning"][k] = cols["detected"][k]
            self._note(k, "no failure threshold: a RUL needs one (--failure LEVEL, or "
                          "--failure 2x the healthy level); detection only")
            return
        if not cols["detected"][k]:
            cols["warning"][k] = self._warn_level(k, y)
            self._note(k, "no change from healthy detected yet: no RUL before one is (the "
                          "tests so far say nothing of when the wear will start)")
            return
        self._rul(k, t, y)

    def _rul(self, k: int, t: float, y: float) -> None:
        assert self.span is not None and self.curve is not None
        cols, ref, sign = self.res.cols, self.ref, self.sign
        f = self.curve.fit(ref.sd / self.span, ref.n)
        rul, u_now = samples(f, self.rng)
        rul = self._mix_local(k, rul)
        lv = ref.level + sign * self.span * _quantiles(u_now, (5, 50, 95))
        cols["level_p5"][k], cols["level_p50"][k], cols["level_p95"][k] = (
            (lv[0], lv[1], lv[2]) if sign > 0 else (lv[2], lv[1], lv[0]))
        if self.s.keep_samples:
            self.res.samples[k] = rul[:self.s.keep_samples].copy()
        q = _quantiles(np.minimum(rul, BIG), PCT)
        q[q >= 1e-3 * BIG] = math.inf      # never reached (BIG in the interpolation)
        # a percentile beyond the horizon is given as the horizon ("at least"), flagged
        hor = HORIZON * max(t - float(self.tr.t[0]), ref.dt)
        cols["rul_open"][k] = float(q[4] > hor)
        for c, v in zip(PCT, np.minimum(q, hor), strict=True):
            cols[f"rul_p{c}"][k] = v
        cols["toe_p50"][k] = t + min(q[2], hor)
        cols["warning"][k] = self._warn_level(k, float(lv[1]))
        if k >= ref.n:
            if abs(f.z_last) > FIT_Z:
                self.unfit_since, self.fit_run = t, 0
                self.res.events.setdefault("left_range_t", t)
            else:
                self.fit_run += 1
        if f.widened > WIDE:
            self._note(k, f"the tests scatter {f.widened:.2g} times the healthy tests' noise "
                          "about the fitted curves: the band is that much wider")
        self._trust(k, t, y, q, rul)

    def _mix_local(self, k: int, rul: np.ndarray) -> np.ndarray:
        """The RUL draws of the two models (`bench.hums.trend_model`, "Two models"): a
        share P_LOCAL of the curve's draws, at random places, replaced by the local drift
        model's on the tests since the change."""
        assert self.span is not None
        tr = self.tr
        j = int(np.searchsorted(tr.t, self.res.events["change_t"]))
        j = max(min(j, k + 1 - LOCAL_MIN), 0)
        t = tr.t[j:k + 1]
        u = self.sign * (tr.y[j:k + 1] - self.ref.level) / self.span
        m = int(round(P_LOCAL * len(rul)))
        out = rul.copy()
        loc = local_drift(t, u, float(self.res.events["change_t"]), self.rng, m)
        hor = HORIZON * max(float(tr.t[k] - tr.t[0]), self.ref.dt)
        out[self.rng.permutation(len(rul))[:m]] = np.where(loc < hor, loc, np.inf)
        return out

    def _warn_level(self, k: int, level: float) -> float:
        """The warning: the level past the warning level when one is given, else the
        detection."""
        warn = self.res.warning_level
        if warn is None:
            return float(self.res.cols["detected"][k])
        return float(self.sign * (level - warn) >= 0)

    def _trust(self, k: int, t: float, y: float, q: np.ndarray, rul: np.ndarray) -> None:
        """The notes that say when this band cannot be trusted."""
        ref, sign, tr = self.ref, self.sign, self.tr
        fail = self.res.failure
        assert fail is not None
        if math.isfinite(self.unfit_since) and self.fit_run < 3:
            self._note(k, f"the trend left the model's range on {tr.date(self.unfit_since)} "
                          f"(a test {FIT_Z:g} sd or more from the best curve): the band "
                          "widens as the noise estimate grows, not at once")
        if sign * (y - fail) >= 0:
            self._note(k, f"the test is past the failure threshold ({y:.4g} against "
                          f"{fail:.4g}): the RUL is that of the level the model filters")
        dev = sign * (y - ref.level) / self.res.cols["noise"][k]
        if dev < -6.0:
            self._note(k, f"the test is {-dev:.0f} sd on the healthy side of the reference: "
                          "outside the range the model covers (check the unit and the "
                          "direction, --decreasing)")
        if not np.isfinite(q[4]) or float(np.mean(~np.isfinite(rul))) > 0.05:
            self._note(k, "the band is open above: more than 5 % of the curves the tests "
                          f"allow do not reach the threshold within {HORIZON:g} times the "
                          "time the tests span (that horizon is given as the percentiles "
                          "beyond it, rul_open)")
        if np.isfinite(q[4]) and q[4] - q[0] < 0.25 * ref.dt:
            self._note(k, "the band is a single value: every curve the tests allow is past "
                          "the threshold"
                       if q[4] == 0 else f"the band is narrower than a quarter of a test "
                       f"interval ({q[4] - q[0]:.3g} {self.s.time_unit})")

    def _summary(self) -> None:
        ref, unit, ev = self.ref, self.res.unit, self.res.events
        u = f" {unit}" if unit else ""
        self.res.notes.append(
            f"healthy reference: {ref.requested}: level {ref.level:.4g}{u}, sd "
            f"{ref.sd:.3g}{u} (+-3 sd: {ref.level - 3 * ref.sd:.4g} to "
            f"{ref.level + 3 * ref.sd:.4g}{u})" + (
                "; few healthy tests make a wide reference" if ref.n < 4 else ""))
        if self.res.failure is None:
            self.res.notes.append("no failure threshold: a RUL needs one (--failure LEVEL, "
                                  "or --failure 2x the healthy level); detection only")
        if "detected_t" not in ev and ref.n >= len(self.tr.t):
            self.res.notes.append(f"every test is in the healthy reference ({ref.requested}):"
                                  " none is left to judge")
        elif "detected_t" not in ev:
            self.res.notes.append("no change from healthy detected")


