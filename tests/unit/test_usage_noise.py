"""The usage counters' hysteresis against the log's own noise (bench/usage/hysteresis.py,
docs/usage.md "Hysteresis"): a noisy position counts its motion, not its noise; the
bench's own LVDT noise keeps the setting; an explicit setting is a floor; the load's rule
is off by default (a rough gust load is not noise) and can be switched on."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.signals.trace import Trace
from bench.usage import UsageAccumulator, UsageSettings, accumulate, usage_of_trace
from bench.usage.accumulator import Geometry
from plant_rt.params import PlantParams


def off() -> UsageSettings:
    """The position setting alone, the rule off: the counts before the rule (built in
    the tests, so that on the code before the rule they fail on counts, not on a name)."""
    return UsageSettings(position_noise_factor=0.0)


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    """Load the compiled tracker (numba's disk cache) once, outside the tests' time."""
    from bench.usage.tracker import Tracker
    Tracker(1.0).push(np.zeros(2))


def noisy_sine(fs: float, seed: int = 0, noise_m: float = 0.2e-3) -> Trace:
    """Ten periods of a slow 1 mm sine (0.5 Hz, from a valley to a valley) with white
    position noise."""
    n = int(10 / 0.5 * fs) + 1
    t = np.arange(n) / fs
    x = -1e-3 * np.cos(2 * math.pi * 0.5 * t)
    x += np.random.default_rng(seed).normal(0.0, noise_m, n)
    return Trace({"t_s": t, "position_m": x}, {"period_s": 1 / fs})


@pytest.mark.parametrize("fs", [1000.0, 25.0])
def test_a_noisy_sine_counts_its_periods_not_its_noise(fs):
    tr = noisy_sine(fs)
    s = usage_of_trace(tr)
    assert s.position_cycles == 10.0                 # the sine's ten periods
    assert s.position_hysteresis_m == pytest.approx(2e-3, rel=0.05)   # 10 x 0.2 mm
    assert "= 10 x the log's position noise 0.2" in s.hysteresis["position"]
    assert s.hysteresis["position"].endswith("(setting 20 um)")
    raw = usage_of_trace(tr, off())                    # 20 um: the noise closes cycles
    # measured: 6471 cycles at 1 kHz, 145 at 25 Hz (the same before the rule)
    assert raw.position_cycles > 50 * fs / 25
    assert raw.position_hysteresis_m == 20e-6
    assert raw.hysteresis["position"] == "20 um (setting; noise rule off: " \
                                         "usage.position_noise_factor=0)"


def test_the_bench_lvdt_noise_keeps_the_setting():
    """2 um of noise is the noise the 20 um default was chosen for: its estimate falls on
    either side of 2 um, and the setting stays (so do the counts)."""
    n = 4000
    t = np.arange(n) * 1e-3
    above = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        x = 2e-3 * np.sin(2 * math.pi * 1.5 * t) + rng.normal(0, 2e-6, n)
        tr = Trace({"t_s": t, "position_m": x}, {"period_s": 1e-3})
        s, alone = usage_of_trace(tr), usage_of_trace(tr, off())
        assert s.position_hysteresis_m == 20e-6, seed
        why = s.hysteresis["position"]
        assert why.startswith("20 um (setting; the log's position noise "), why
        above += "is within its estimate's scatter of 2 um" in why
        a, b = s.as_dict(), alone.as_dict()
        assert a.keys() == b.keys()
        assert all(a[k] == b[k] or math.isnan(a[k]) and math.isnan(b[k]) for k in a), seed
    # on some seeds the estimate fell above 2 um: a plain max(20 um, 10 x noise) would
    # have raised the setting there
    assert 0 < above < 20


def test_an_explicit_setting_is_a_floor_too():
    tr = noisy_sine(100.0)
    big = usage_of_trace(tr, UsageSettings(position_hysteresis_m=5e-3))
    assert big.position_hysteresis_m == 5e-3                     # above 10 x the noise
    assert big.hysteresis["position"].startswith("5 mm (setting; the log's position noise")
    small = usage_of_trace(tr, UsageSettings(position_hysteresis_m=1e-3))
    assert small.position_hysteresis_m == pytest.approx(2e-3, rel=0.05)
    assert small.hysteresis["position"].endswith("(setting 1 mm)")
    assert small.position_cycles == 10.0


def test_the_load_rule_is_off_by_default_and_measures_when_on():
    """A first-order coloured load (the bench's aero gusts: 1 kN std, 0.5 s) has second
    differences like white noise of ~36 N at 1 kHz: real load, so the default keeps
    100 N. A load cell's white noise is what the rule is for, when switched on."""
    n, dt, tau = 20000, 1e-3, 0.5
    rng = np.random.default_rng(5)
    a = math.exp(-dt / tau)
    w = rng.normal(0.0, 1000.0 * math.sqrt(1 - a * a), n)
    gust = np.zeros(n)
    for k in range(1, n):
        gust[k] = a * gust[k - 1] + w[k]
    t = np.arange(n) * dt
    tr = Trace({"t_s": t, "load_force_n": gust}, {"period_s": dt})
    s = usage_of_trace(tr)
    assert s.load_hysteresis_n == 100.0
    assert s.hysteresis["load"] == "100 N (setting; noise rule off: usage.load_noise_factor=0)"
    on = usage_of_trace(tr, UsageSettings(load_noise_factor=10.0))
    assert on.load_hysteresis_n > 300.0                    # the gust's roughness read as noise
    assert on.load_cycles < s.load_cycles / 3
    # a load cell's white noise, 50 N on a 3 Hz sine: 500 N with the rule
    cell = -2000 * np.cos(2 * math.pi * 3 * t) + rng.normal(0.0, 50.0, n)
    noisy = Trace({"t_s": t, "load_force_n": cell}, {"period_s": dt})
    on = usage_of_trace(noisy, UsageSettings(load_noise_factor=10.0))
    assert on.load_hysteresis_n == pytest.approx(500.0, rel=0.05)
    assert on.load_cycles == 60.0                           # 3 Hz x 20 s
    assert usage_of_trace(noisy).load_cycles > 1000
    # a constant load (a rig's nominal weight) or none: the setting, and says why
    const = usage_of_trace(Trace({"t_s": t, "load_force_n": np.full(n, 392.3)},
                                 {"period_s": dt}), UsageSettings(load_noise_factor=10.0))
    assert const.hysteresis["load"] == "100 N (setting; the log's load noise 0 N)"
    assert usage_of_trace(Trace({"t_s": t}, {"period_s": dt})).hysteresis == {
        "reversal": "2 um (setting; on the encoder angle, no noise rule)",
        "position": "20 um (setting; no measured position_m)",
        "load": "100 N (setting; noise rule off: usage.load_noise_factor=0)"}


def test_what_the_json_and_the_accumulation_say():
    noisy = usage_of_trace(noisy_sine(100.0), serial="3")
    quiet = usage_of_trace(noisy_sine(100.0, noise_m=0.0), serial="3")
    js = noisy.to_json()
    assert js["position_hysteresis_m"] == pytest.approx(2e-3, rel=0.05)
    assert js["hysteresis"]["position"] == noisy.hysteresis["position"]
    assert js["load_hysteresis_n"] == 100.0
    # without noise the estimator reads the sampled sine's curvature, 0.43 A (2 pi f dt)^2
    assert quiet.hysteresis["position"] == "20 um (setting; the log's position noise 0.422 um)"
    acc = accumulate([noisy, quiet])["3"]
    assert acc.position_hysteresis_m == noisy.position_hysteresis_m     # the largest
    assert acc.hysteresis["position"] == "up to 1.97 mm; the runs differ (each run's line " \
                                         "says why)"
    assert acc.hysteresis["reversal"] == noisy.hysteresis["reversal"]
    assert accumulate([noisy, noisy])["3"].hysteresis == noisy.hysteresis
    # the live watcher's accumulator: the settings, and why
    live = UsageAccumulator(0.01, Geometry.of(PlantParams(), UsageSettings()))
    assert live.summary().hysteresis["position"] == "20 um (setting; no noise rule applied)"


def test_the_gap_fit_and_the_rig_tools_share_one_white_noise_estimator():
    """`bench.gap.problem.noise_std` (the fits' weights) and `bench.signals.estimators.noise_floor` (the
    rig tools' floors, the usage hysteresis) were two copies of the same formula; now one
    is the other, but for the fit's 0.0 below 10 finite samples (the floor's NaN)."""
    from bench.gap.problem import noise_std
    from bench.signals.estimators import noise_floor
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(size=500)) * 1e-3 + 0.02 * rng.normal(size=500)
    y[::9] = np.nan
    assert noise_std(y) == noise_floor(y) > 0.0
    assert noise_std(y[:10]) == 0.0 and math.isnan(noise_floor(y[:4]))
