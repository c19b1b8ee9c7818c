"""Synthetic endurance trends to develop and check the trend prognosis on (not real data):
one current-like health index per test over months, a few healthy tests at the start, a
failure at twice the healthy level, of several shapes.

`endurance_trend(shape, seed)` draws one: life 60-240 days; tests daily, every 2-4 days,
or on irregular days (weekends and gaps skipped); a healthy level of 1-5 (amperes, say)
with a noise of 1-4 % (5-9 % and outliers for ``noisy``); the excess over healthy
e = y / h0 - 1 reaches 1 (the failure, 2 x healthy) at the end of life:

- ``linear``: e grows linearly from the first test (wear from day one);
- ``exponential``: flat, then e ~ exp(b (t - onset)) from an onset at 10-50 % of life;
- ``piecewise``: flat, then a straight rise from an onset at 20-60 % of life;
- ``knee``: a slow rise to 15-35 % at 60-85 % of life, then a steep one;
- ``jam``: a slow exponential rise to 20-50 %, then the index jumps past the failure on
  the day of the jam (a seized screw: nothing in the trend foretells the day);
- ``noisy``: one of the above with 5-9 % noise, a slow wander (an AR(1) of the test
  conditions) and 5 % of tests with a three-times noise;
- ``healthy``: no degradation (for false alarms), no failure.

The truth is the day the noise-free index reaches the failure level (the jam's day for
``jam``). `write_csv` writes trends as the CSV `bench hums prognose --trends` reads,
with dates or days.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from datetime import date, timedelta
from pathlib import Path

import numpy as np

from bench import BenchError

SHAPES = ("linear", "exponential", "piecewise", "knee", "jam", "noisy", "healthy")
FAILURE_RATIO = 2.0
START = date(2024, 1, 8)


@dataclass
class SynthTrend:
    """One synthetic endurance test: test days, index values, the truth."""
    name: str
    shape: str
    t: np.ndarray               # test days (days since the first test)
    y: np.ndarray
    healthy_level: float
    t_failure: float            # day the noise-free index reaches FAILURE_RATIO x healthy
    onset: float                # day the noise-free index starts to move
    unit: str = "A"

    @property
    def failure_level(self) -> float:
        return FAILURE_RATIO * self.healthy_level


def _days(rng: np.random.Generator, life: float, cadence: str) -> np.ndarray:
    """Test days from 0 to the end of life (the last test on the failure day or after)."""
    if cadence == "daily":
        t = np.arange(0.0, life + 1.0)
    elif cadence == "every":
        t = np.arange(0.0, life + 4.0, float(rng.integers(2, 5)))
    else:               # irregular: working days, a few gaps of a week or two
        t = np.arange(0.0, life + 1.0)
        t = t[(t % 7) < 5]
        keep = rng.random(len(t)) < 0.6
        keep[:4] = True
        t = t[keep]
    return t


def _excess(shape: str, t: np.ndarray, life: float, rng: np.random.Generator
            ) -> tuple[np.ndarray, float]:
    """Noise-free excess over healthy (1 = failure at `life`) and the onset day."""
    if shape == "linear":
        return t / life, 0.0
    if shape == "exponential":
        on = life * rng.uniform(0.1, 0.5)
        b = rng.uniform(2.0, 5.0) / (life - on)
        e = np.expm1(b * np.maximum(t - on, 0.0)) / math.expm1(b * (life - on))
        return e, on
    if shape == "piecewise":
        on = life * rng.uniform(0.2, 0.6)
        return np.maximum(t - on, 0.0) / (life - on), on
    if shape == "knee":
        on = life * rng.uniform(0.0, 0.3)
        tk = life * rng.uniform(0.6, 0.85)
        ek = rng.uniform(0.15, 0.35)
        slow = ek * np.maximum(t - on, 0.0) / (tk - on)
        fast = ek + (1.0 - ek) * (t - tk) / (life - tk)
        return np.where(t < tk, slow, fast), on
    if shape == "jam":
        on = life * rng.uniform(0.1, 0.5)
        ej = rng.uniform(0.2, 0.5)
        b = rng.uniform(1.0, 3.0) / (life - on)
        e = ej * np.expm1(b * np.maximum(t - on, 0.0)) / math.expm1(b * (life - on))
        return np.where(t >= life, rng.uniform(1.2, 2.0), e), on
    if shape == "healthy":
        return np.zeros_like(t), math.inf
    raise ValueError(f"unknown shape {shape!r} (known: {', '.join(SHAPES)})")


def endurance_trend(shape: str, seed: int, cadence: str | None = None) -> SynthTrend:
    """One synthetic endurance trend (module docstring)."""
    rng = np.random.default_rng(seed)
    life = float(rng.uniform(60.0, 240.0))
    cad = cadence or str(rng.choice(["daily", "every", "irregular"]))
    base = str(rng.choice(SHAPES[:5])) if shape == "noisy" else shape
    t = _days(rng, life, cad)
    if base == "jam":
        t = np.unique(np.append(t[t < life], math.floor(life)))
        life = math.floor(life)
    e, onset = _excess(base, t, life, rng)
    h0 = float(rng.uniform(1.0, 5.0))
    cv = rng.uniform(0.05, 0.09) if shape == "noisy" else rng.uniform(0.01, 0.04)
    noise = rng.normal(0.0, cv, len(t))
    if shape == "noisy":
        wander = np.zeros(len(t))
        for k in range(1, len(t)):
            wander[k] = 0.8 * wander[k - 1] + rng.normal(0.0, 0.3 * cv)
        out = rng.random(len(t)) < 0.05
        noise = noise * np.where(out, 3.0, 1.0) + wander
        noise[:3] = rng.normal(0.0, cv, 3)
    y = h0 * (1.0 + e + noise)
    t_f = math.inf if base == "healthy" else float(life)
    if base != "healthy":
        keep = t <= t_f + 1e-9
        t, y = t[keep], y[keep]
    return SynthTrend(f"{shape}-{seed}", shape, t, y, h0, t_f, onset)


def write_csv(trends: list[SynthTrend], path: str | Path, dates: bool = True,
              index: str = "rms_current", unit: str = "A") -> Path:
    """The trends as a long-form CSV (time as dates or days, actuator, index, value,
    unit). BenchError, one line, when the file cannot be written."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with p.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["date" if dates else "day", "actuator", "index", "value", "unit"])
            for tr in trends:
                for t, y in zip(tr.t, tr.y, strict=True):
                    when = (START + timedelta(days=float(t))).isoformat() if dates \
                        else f"{t:g}"
                    w.writerow([when, tr.name, index, f"{y:.5g}", unit])
    except OSError as exc:
        raise BenchError(f"cannot write {p}: {exc.strerror or exc}") from None
    return p


def main(argv: list[str] | None = None) -> int:
    """``python -m bench.hums.trend_synth --shape S --seed N --out F.csv``: synthetic
    trends as a CSV (one actuator per shape and seed; the truth on stdout)."""
    import argparse
    ap = argparse.ArgumentParser(description="synthetic endurance trends (not real data)")
    ap.add_argument("--shape", nargs="+", default=["exponential"], choices=SHAPES)
    ap.add_argument("--seed", type=int, nargs="+", default=[7])
    ap.add_argument("--days", action="store_true", help="days, not dates")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    trends = [endurance_trend(sh, sd) for sh, sd in zip(a.shape, a.seed, strict=True)]
    try:
        write_csv(trends, a.out, dates=not a.days)
    except BenchError as exc:
        ap.error(str(exc))
    for tr in trends:
        when = (START + timedelta(days=tr.t_failure)).isoformat() if math.isfinite(
            tr.t_failure) else "never"
        print(f"{tr.name}: {len(tr.t)} tests, healthy level {tr.healthy_level:.4g} "
              f"{tr.unit}, failure level {tr.failure_level:.4g} {tr.unit} reached on {when} "
              f"(day {tr.t_failure:.1f})")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    import sys
    sys.exit(main())
