"""The hindsight limits of an index that benchmarks/eval_trend_prognosis.py reports beside
the trend's own prognosis on the campaign."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from eval_trend_prognosis import _limits_summary, index_limits  # noqa: E402


def _trend(u_of_t, limit: float = 3.0, h0: float = 1.0) -> dict[float, float]:
    t = np.arange(0.0, 41.0)
    return dict(zip(t, h0 + (limit - h0) * u_of_t(t), strict=True))


def test_a_straight_line_to_the_threshold_is_its_own_extrapolation():
    lim = index_limits(_trend(lambda t: t / 40.0), 40.0, 3.0, 3)
    assert lim["rate_ratio"] == pytest.approx(1.0, abs=1e-9)
    assert lim["u_fail"] == pytest.approx(1.0, abs=1e-9)
    assert lim["line_ok"] == 1.0


def test_a_rate_that_slows_is_seen_and_defeats_the_recent_line():
    """u = 1 - (1 - t / 40)^2: the rate after 70 % of life is half the earlier one, and
    the earlier line reaches the threshold in 12 * 0.57 days instead of 12."""
    lim = index_limits(_trend(lambda t: 1.0 - (1.0 - t / 40.0) ** 2), 40.0, 3.0, 3)
    assert 0.3 < lim["rate_ratio"] < 0.7
    assert lim["line_ok"] == 0.0


def test_a_failure_short_of_the_threshold_and_the_spread_about_each_threshold():
    lims = [index_limits(_trend(lambda t, s=s: s * t / 40.0), 40.0, 3.0, 3)
            for s in (0.8, 1.0, 1.2)]
    # the healthy level is the mean of tests 0-2 (day 1), the failure the index on day 40
    want = [2.0 * s * 39.0 / 40.0 / (2.0 - 2.0 * s / 40.0) for s in (0.8, 1.0, 1.2)]
    assert [x["u_fail"] for x in lims] == pytest.approx(want, abs=1e-9)
    s = _limits_summary(lims)
    assert s["u_fail_range"][0] < 0.85 and s["u_fail_range"][1] > 1.2
    assert s["cv_threshold"] > 0.05 and s["cv_healthy"] > 0.05
