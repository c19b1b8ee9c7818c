"""Endurance trends of laws the trend prognosis was not developed on: its final check.

`bench.hums.trend_synth` draws the shapes the model (`bench.hums.trend_model`) was
developed on: straight, exponential, piecewise, knee, jam. A model fitted to those says
little about a rig whose wear follows another law. This generator draws others, and
its seeds are fixed here (`FINAL_SEED`), apart from every development and held-out
seed (`tests/unit/test_trend_check_seeds.py`); the results are measured with them, not
tuned on them:

- ``power``: power-law wear, e = ((t - onset) / (life - onset))^p, p 1.5-3, onset at
  0-40 % of life;
- ``paris``: a crack growing by Paris' law, da/dt = C a^m (m 2-4): from a0 at the
  onset (10-50 % of life) a(t) = a0 (1 - (t - onset) / T)^(-1 / (m - 1)), which blows
  up at onset + T; the index's excess is (a - a0) / (a_f - a0), the failure at
  a_f = 3-10 a0;
- ``gamma``: a gamma process (van Noortwijk 2009): independent gamma increments of
  mean shape (t - onset)^q (q 1-2) and a coefficient of variation of the increments
  per tenth of life of about 0.3-0.8, on a quarter-day grid;
- ``wiener``: a drift with Brownian motion on top (Si et al. 2011) from the onset, its
  diffusion 0.05-0.15 of the way to failure per square root of a tenth of life;
- ``seasonal``: power-law wear under a slow wander of the test conditions, a sine of
  30-120 days and 1-3 % of the healthy level (temperature);
- ``healthy-seasonal``: that wander alone (for false alarms), no failure.

Test days, healthy level (1-5) and noise (1-4 %) as `trend_synth`. The truth is the first
time the noise-free index reaches twice the healthy level: of the random processes, on
the quarter-day grid their paths are drawn on. ``python -m bench.hums.trend_check --law
paris --trend 0 --out F.csv`` writes trends as the CSV `bench hums prognose` reads.
"""

from __future__ import annotations

import math

import numpy as np

from bench import BenchError
from bench.hums.trend_synth import SynthTrend, _days

SHAPES = ("power", "paris", "gamma", "wiener", "seasonal", "healthy-seasonal")
FINAL_SEED = 7300          # trend k of shape s: FINAL_SEED + 100 s + k
GRID = 0.25                # days: the grid the random paths are drawn on


def _paths(shape: str, rng: np.random.Generator, life: float
           ) -> tuple[np.ndarray, np.ndarray, float]:
    """The noise-free excess on a fine grid (1 = failure), its grid, and the onset."""
    tg = np.arange(0.0, 3.0 * life, GRID)
    if shape in ("power", "seasonal"):
        on = life * rng.uniform(0.0, 0.4)
        p = rng.uniform(1.5, 3.0)
        return tg, (np.clip(tg - on, 0.0, None) / (life - on)) ** p, on
    if shape == "paris":
        on = life * rng.uniform(0.1, 0.5)
        m = rng.uniform(2.0, 4.0)
        ratio = rng.uniform(3.0, 10.0)                   # a_f / a0
        # a reaches a_f at life: (1 - (life - on) / T)^(-1/(m-1)) = ratio
        T = (life - on) / (1.0 - ratio ** (1.0 - m))
        x = np.clip((tg - on) / T, 0.0, 1.0 - 1e-12)
        a = (1.0 - x) ** (-1.0 / (m - 1.0))
        return tg, (a - 1.0) / (ratio - 1.0), on
    on = life * rng.uniform(0.0, 0.4)
    s = np.clip(tg - on, 0.0, None) / (life - on)
    if shape == "gamma":
        q = rng.uniform(1.0, 2.0)
        cv = rng.uniform(0.3, 0.8)       # of the increment over a tenth of the wear life
        # increments of the mean s^q; their shape such that a tenth's cv is `cv`
        mean = np.diff(s ** q, prepend=0.0)
        k = 1.0 / (cv * cv) / (0.1 ** q)  # shape per unit of mean
        inc = rng.gamma(np.maximum(k * mean, 1e-12), 1.0 / k)
        return tg, np.cumsum(inc), on
    if shape == "wiener":
        sd = rng.uniform(0.05, 0.15) / math.sqrt(0.1 * (life - on))
        steps = rng.normal(0.0, sd * math.sqrt(GRID), len(tg)) * (tg > on)
        return tg, s + np.cumsum(steps), on
    raise ValueError(f"unknown shape {shape!r} (known: {', '.join(SHAPES)})")


def final_trend(shape: str, k: int) -> SynthTrend:
    """Trend `k` (0 to 99) of `shape` of the final check (module docstring)."""
    if not 0 <= k < 100:
        raise ValueError(f"trend {k}: the final check has trends 0 to 99 of each law")
    seed = FINAL_SEED + 100 * SHAPES.index(shape) + k
    rng = np.random.default_rng(seed)
    life = float(rng.uniform(60.0, 240.0))
    cad = str(rng.choice(["daily", "every", "irregular"]))
    h0 = float(rng.uniform(1.0, 5.0))
    cv = rng.uniform(0.01, 0.04)
    if shape == "healthy-seasonal":
        t, e, t_f, on = _days(rng, life, cad), None, math.inf, math.inf
    else:
        tg, eg, on = _paths(shape, rng, life)
        hit = np.flatnonzero(eg >= 1.0)
        t_f = float(tg[hit[0]]) if len(hit) else math.inf     # a path that never fails
        t = _days(rng, t_f if len(hit) else life, cad)
        t = t[t <= t_f]
        e = np.interp(t, tg, eg)
    y = h0 * (1.0 + (0.0 if e is None else e) + rng.normal(0.0, cv, len(t)))
    if shape in ("seasonal", "healthy-seasonal"):
        period, amp = rng.uniform(30.0, 120.0), rng.uniform(0.01, 0.03)
        y = y + h0 * amp * np.sin(2.0 * math.pi * t / period + rng.uniform(0, 2 * math.pi))
    return SynthTrend(f"{shape}-{seed}", shape, t, y, h0, t_f, on)


def main(argv: list[str] | None = None) -> int:
    """``python -m bench.hums.trend_check --law L --trend K --out F.csv``: final-check
    trends as the CSV `bench hums prognose --trends` reads (the truth on stdout)."""
    import argparse
    from datetime import datetime, timedelta

    from bench.hums.trend_synth import START, write_csv
    ap = argparse.ArgumentParser(description="final-check endurance trends (not real data)")
    ap.add_argument("--law", nargs="+", default=["paris"], choices=SHAPES)
    ap.add_argument("--trend", type=int, nargs="+", default=[0])
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    if len(a.law) != len(a.trend):
        ap.error("give one --trend per --law")
    try:
        trends = [final_trend(law, k) for law, k in zip(a.law, a.trend, strict=True)]
    except ValueError as exc:
        ap.error(str(exc))
    try:
        write_csv(trends, a.out)
    except BenchError as exc:
        ap.error(str(exc))
    for tr in trends:
        start = datetime(START.year, START.month, START.day)
        when = ("reached on " + (start + timedelta(days=tr.t_failure)).isoformat(
            timespec="minutes")) if math.isfinite(tr.t_failure) else "never reached"
        print(f"{tr.name}: {len(tr.t)} tests, healthy level {tr.healthy_level:.4g} "
              f"{tr.unit}, failure level {tr.failure_level:.4g} {tr.unit} {when}")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    import sys
    sys.exit(main())
