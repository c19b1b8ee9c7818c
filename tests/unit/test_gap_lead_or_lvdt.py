"""An LVDT gain and a lead error move the LVDT per motor angle alike; only the lead moves
the current an axial force costs (T = F lead / (2 pi eta)). The diagnosis compares the
slope of the logged current on the load cell's force with each candidate's, and says
"indistinguishable" where the log cannot tell."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import numpy as np
import pytest

from bench.gap import alias as AL

pytestmark = pytest.mark.unit

N = 4000
T = np.arange(N) * 1e-3
FORCE = 2000.0 * np.sin(2 * math.pi * 0.5 * T)
SLOPE = 0.004 / (2 * math.pi * 0.9 * 0.9)        # A per N: lead / (2 pi eta kt)


def _current(slope: float, noise: float, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return slope * FORCE + 0.3 * np.sin(2 * math.pi * 3.0 * T) + noise * rng.normal(size=N)


def test_the_slope_is_found_with_an_honest_error():
    """The slope within 4 standard errors of the truth on 20 noise draws, and the error
    small enough against a 3 % lead change at 0.05 A of noise."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        y = SLOPE * FORCE + 0.05 * rng.normal(size=N)
        b, se = AL.load_slope(y, FORCE)
        assert abs(b - SLOPE) < 4 * se
        assert se < 0.03 * SLOPE / AL.SEPARATION_Z


def _problem(log_slope: float, noise: float, load: bool = True) -> NS:
    """A stand-in problem whose re-simulation gives each candidate's slope: the lead one
    3 % more current per newton, the LVDT gain one the datasheet's."""
    slopes = {"lead": 1.03 * SLOPE, "lvdt_gain": SLOPE}

    def simulate(objs, theta, n):
        return {"current_a": _current(slopes[objs[0].name], 0.0)[:n]}

    return NS(n=N, meas={"current_a": _current(log_slope, noise)},
              drive=NS(load_n=FORCE if load else None), simulate=simulate)


def _cand(name: str) -> NS:
    return NS(fit=NS(name=name, effects=(name,), objs=[NS(name=name)], theta=[{}],
                     rss=1.0))


@pytest.mark.parametrize("truth", ["lvdt_gain", "lead"])
def test_the_load_cell_tells_the_lead_from_the_lvdt_gain(truth):
    """Before: the kinematics alone chose (an LVDT gain of 1.03 read as a lead of 4.12 mm
    on three builds); now the log's slope picks the candidate whatever came first."""
    p = _problem({"lead": 1.03, "lvdt_gain": 1.0}[truth] * SLOPE, 0.05)
    for first in AL.PAIR:
        second = AL.PAIR[1 - AL.PAIR.index(first)]
        got, rec = AL.settle(p, _cand(first), [_cand(first), _cand(second)])
        assert rec["separated"], rec["why"]
        assert got.fit.name == truth


def test_a_noisy_log_is_called_indistinguishable():
    p = _problem(1.03 * SLOPE, 30.0)
    got, rec = AL.settle(p, _cand("lead"), [_cand("lead"), _cand("lvdt_gain")])
    assert got.fit.name == "lead"
    assert not rec["separated"] and rec["line"] == AL.INDISTINGUISHABLE
    assert "standard errors" in rec["why"]


def test_a_slope_halfway_is_called_indistinguishable():
    p = _problem(1.015 * SLOPE, 0.05)
    _, rec = AL.settle(p, _cand("lvdt_gain"), [_cand("lead"), _cand("lvdt_gain")])
    assert not rec["separated"] and "between" in rec["why"]


def test_without_a_load_cell_nothing_is_decided():
    p = _problem(SLOPE, 0.05, load=False)
    got, rec = AL.settle(p, _cand("lead"), [_cand("lead"), _cand("lvdt_gain")])
    assert got.fit.name == "lead" and not rec["separated"]


def test_other_verdicts_are_left_alone():
    p = _problem(SLOPE, 0.05)
    c = _cand("backlash")
    got, rec = AL.settle(p, c, [c, _cand("lead"), _cand("lvdt_gain")])
    assert got is c and rec is None


def test_the_healthy_log_s_ratio_takes_out_what_the_model_misses():
    """The calibrated model costs 15 % more current per newton than the actuator (its
    efficiency): on the log's own scale the log lies beyond both candidates; scaled by
    the healthy log's ratio the LVDT gain is the one."""
    p = _problem(0.85 * SLOPE, 0.05)
    pair = [_cand("lead"), _cand("lvdt_gain")]
    _, rec = AL.settle(p, _cand("lead"), pair)
    assert not rec["separated"] and "beyond" in rec["why"]
    got, rec = AL.settle(p, _cand("lead"), pair, ratio=0.85)
    assert rec["separated"] and got.fit.name == "lvdt_gain"
