"""The local drift model of the trend prognosis (bench.hums.trend_model.local_drift): the
crossing of the recent tests' line, its Student-t band, its window, its two edges; and
the mix of the two models on a power-law wear, where the curve alone was early."""

from __future__ import annotations

import numpy as np
import pytest

from bench.hums.trend_io import Trend
from bench.hums.trend_model import local_drift
from bench.hums.trend_prognosis import Settings, prognose


def test_a_straight_line_crosses_where_it_should_and_the_band_holds_it():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 51.0)
    u = 0.01 * t + rng.normal(0.0, 0.005, len(t))
    rul = local_drift(t, u, 0.0, np.random.default_rng(2), 4000)
    p5, p50, p95 = np.percentile(rul, [5, 50, 95])
    assert p50 == pytest.approx(50.0, rel=0.05)     # (1 - 0.5) / 0.01
    assert p5 < 50.0 < p95
    assert p95 - p5 > 2.0                           # a band, not a point


def test_only_the_later_half_since_the_change_sets_the_drift():
    t = np.arange(0.0, 51.0)
    u = np.where(t < 25.0, 0.005 * t, 0.125 + 0.02 * (t - 25.0))   # the rate quadruples
    u = u + np.random.default_rng(3).normal(0.0, 1e-4, len(t))
    rul = local_drift(t, u, 0.0, np.random.default_rng(4), 2000)
    assert np.median(rul) == pytest.approx((1.0 - u[-1]) / 0.02, rel=0.02)


def test_past_the_threshold_is_zero_and_a_falling_trend_never_crosses():
    t = np.arange(0.0, 20.0)
    rng = np.random.default_rng(5)
    past = local_drift(t, 1.2 + 0.01 * t + rng.normal(0, 1e-3, 20), 0.0, rng, 200)
    assert np.all(past == 0.0)
    falling = local_drift(t, 0.5 - 0.01 * t + rng.normal(0, 1e-3, 20), 0.0, rng, 200)
    assert np.all(np.isinf(falling))


def test_power_law_wear_has_the_truth_in_the_band_at_70_percent_of_life():
    """u = ((t - 5) / 55)^1.5, 1 % noise, failure on day 60, as of day 42: the curve
    alone extrapolated the acceleration as an exponential and its band ended before
    the truth on 4 of these 5 trends."""
    t = np.arange(0.0, 43.0)
    u = (np.clip(t - 5.0, 0.0, None) / 55.0) ** 1.5
    for seed in range(5):
        y = 2.0 * (1.0 + u) + np.random.default_rng(seed).normal(0.0, 0.02, len(t))
        r = prognose(Trend("p", "rms", "A", t, y, np.arange(len(t))),
                     Settings(healthy="5", failure="4.0"))
        assert r.cols["rul_p5"][-1] <= 18.0 <= r.cols["rul_p95"][-1], seed


def test_a_steep_exponential_rise_is_not_capped_by_the_rate_prior():
    """An excess rising exp(5 (t - 75) / 75) from day 75 to the failure on day 150, 1 %
    noise, daily tests: near the end the curve needs kappa = g (t_now - t_0) of ~9
    e-folds. With the prior over kappa cut at 6 the band as of day 130 ended before the
    truth (p5 28 days, truth 20) and held it on none of the days after the warning."""
    life, on = 150.0, 75.0
    t = np.arange(0.0, life)
    e = np.expm1(5.0 / (life - on) * np.clip(t - on, 0.0, None)) / np.expm1(5.0)
    y = 2.0 * (1.0 + e + np.random.default_rng(3).normal(0.0, 0.01, len(t)))
    r = prognose(Trend("x", "rms", "A", t, y, np.arange(len(t))),
                 Settings(healthy="5", failure="4.0"))
    c = r.cols
    assert c["rul_p5"][130] <= 20.0 <= c["rul_p95"][130]
    after = [k for k in range(len(t)) if c["warning"][k] > 0]
    inside = [c["rul_p5"][k] <= life - t[k] <= c["rul_p95"][k] for k in after]
    assert len(after) > 30 and np.mean(inside) >= 0.4
