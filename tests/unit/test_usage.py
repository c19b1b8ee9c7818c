"""Usage monitoring (bench/usage): life consumed against hand calculations,
rainflow on the ASTM E1049 example, reversals under noise, blocks of rows against the
whole trace (the live watcher's totals equal the log's), accumulation per actuator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import BenchError
from bench.signals.trace import Trace
from bench.usage import UsageAccumulator, UsageSettings, accumulate, usage_of_trace
from bench.usage.accumulator import Geometry
from bench.usage.life import nut_loads
from plant_rt.params import PlantParams

P0 = PlantParams()
LEAD, RATIO, CA = P0.screw.lead_m, P0.reducer.ratio, P0.screw.dynamic_load_rating_n
DT = 1e-3
EXACT = UsageSettings(reversal_hysteresis_m=0.0)   # every revolution counts


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    """Load the compiled tracker (numba's disk cache) once, outside the tests' time."""
    from bench.usage.tracker import Tracker
    Tracker(1.0).push(np.zeros(2))


def trace_of(screw_rev_steps: np.ndarray, load_n: np.ndarray, **cols) -> Trace:
    """A synthetic trace: screw revolution increments per sample (the first sample is the
    start) and the load under which each increment is made."""
    rev = np.cumsum(screw_rev_steps)
    n = len(rev)
    columns = {"t_s": np.arange(n) * DT, "motor_angle_rad": rev * 2 * math.pi / RATIO,
               "load_force_n": np.asarray(load_n, float), **cols}
    return Trace(columns, {"period_s": DT})


def test_constant_load_life_consumed_by_hand():
    n, step, f = 5001, 0.002, 5000.0        # 2 rev/s for 5 s under 5 kN
    steps = np.full(n, step)
    steps[0] = 0.0
    s = usage_of_trace(trace_of(steps, np.full(n, f)), EXACT)
    revs = 5000 * 0.002                     # 10 revolutions
    l10 = (22000.0 / 5000.0) ** 3 * 1e6     # 85.184e6 revolutions
    assert CA == 22000.0
    assert s.screw_revolutions == pytest.approx(revs, rel=1e-9)
    assert s.nut_travel_m == pytest.approx(revs * 5e-3, rel=1e-9)
    assert s.fm_n == pytest.approx(5000.0, rel=1e-9)
    assert s.l10_rev == pytest.approx(85.184e6, rel=1e-9)
    assert s.life_consumed == pytest.approx(revs / l10, rel=1e-9)   # 1.1739e-7
    assert s.life_consumed == pytest.approx(1.17393e-7, rel=1e-5)
    assert s.reversals == 0
    # the default hysteresis costs half its width once (2 um / 5 mm / 2 = 2e-4 rev)
    d = usage_of_trace(trace_of(steps, np.full(n, f)))
    assert d.screw_revolutions == pytest.approx(revs - 2e-4, rel=1e-9)


def test_two_level_load_life_consumed_by_hand():
    # 3 rev at 4 kN (1 rev/s for 3 s), then 4 rev at -8 kN (2 rev/s for 2 s)
    steps = np.concatenate([[0.0], np.full(3000, 0.001), np.full(2000, 0.002)])
    load = np.concatenate([[4000.0], np.full(3000, 4000.0), np.full(2000, -8000.0)])
    s = usage_of_trace(trace_of(steps, load), EXACT)
    n1, n2 = 3.0, 4.0
    d = n1 / ((22.0 / 4.0) ** 3 * 1e6) + n2 / ((22.0 / 8.0) ** 3 * 1e6)
    # = 3 / 166.375e6 + 4 / 20.796875e6 = 1.80316e-8 + 1.92337e-7 = 2.10369e-7
    assert d == pytest.approx(2.10369e-7, rel=1e-5)
    fm = ((n1 * 4000.0 ** 3 + n2 * 8000.0 ** 3) / (n1 + n2)) ** (1 / 3)   # 6805.4 N
    assert s.screw_revolutions == pytest.approx(7.0, rel=1e-9)
    assert s.fm_n == pytest.approx(fm, rel=1e-9)
    assert s.life_consumed == pytest.approx(d, rel=1e-9)
    assert s.life_consumed == pytest.approx(s.screw_revolutions / s.l10_rev, rel=1e-9)
    # load spectrum: revolutions per 500 N bin, the two levels only
    assert s.load_spectrum_rev.sum() == pytest.approx(7.0, rel=1e-9)
    assert sorted(np.flatnonzero(s.load_spectrum_rev)) == [1 + 24, 1 + 48]
    assert s.load_max_n == 4000.0 and s.load_min_n == -8000.0


def test_double_nut_preload_shares_the_load():
    f1, f2 = nut_loads(np.array([0.0, 2.0 ** 1.5 * 1000.0, -5000.0]), 1000.0)
    assert f1 == pytest.approx([1000.0, 2.0 ** 1.5 * 1000.0, 0.0])
    assert f2 == pytest.approx([1000.0, 0.0, 5000.0])
    # no external load: both nuts carry the preload; the pair lives 2^(-9/10) as long
    steps = np.concatenate([[0.0], np.full(1000, 0.002)])
    st = UsageSettings(reversal_hysteresis_m=0.0, preload_mode="double-nut", preload_n=3000.0)
    s = usage_of_trace(trace_of(steps, np.zeros(1001)), st)
    one = 2.0 / ((22000.0 / 3000.0) ** 3 * 1e6)
    assert s.damage == 0.0
    assert s.damage_nut1 == pytest.approx(one, rel=1e-9)
    assert s.life_consumed == pytest.approx(2.0 ** 0.9 * one, rel=1e-9)


def test_rainflow_counts_the_astm_e1049_example():
    # ASTM E1049-85 fig. 6 (peaks and valleys in mm): ranges 3 (1/2), 4 (3/2), 6 (1/2),
    # 8 (1), 9 (1/2): 4 cycles
    pts = np.array([-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]) * 1e-3
    legs = [np.linspace(a, b, 50, endpoint=False)
            for a, b in zip(pts[:-1], pts[1:], strict=True)]
    x = np.concatenate([*legs, pts[-1:]])
    s = usage_of_trace(Trace({"t_s": np.arange(len(x)) * DT, "position_m": x},
                             {"period_s": DT}))
    assert s.position_cycles == 4.0
    assert s.position_range_max_m == pytest.approx(9e-3)
    by_range = s.position_rainflow.sum(axis=1)          # range bins 2-5 mm, 5-10 mm
    assert by_range[6] == pytest.approx(2.0) and by_range[7] == pytest.approx(2.0)
    assert by_range.sum() == pytest.approx(4.0)


def test_reversals_with_noise_count_only_the_motion():
    rng = np.random.default_rng(7)
    t = np.arange(6000) * DT
    nut = 1e-3 * np.sin(2 * math.pi * t)                 # 5 periods, then a 1 s dwell
    nut[5000:] = 0.0
    nut += rng.normal(0.0, 0.1e-6, len(t))      # noise, 0.1 um of nut (a count: 0.076 um)
    nut[5000:] += 0.5e-6 * np.sign(np.sin(2 * math.pi * 40 * t[5000:]))   # dither at rest
    rev = nut / LEAD
    tr = Trace({"t_s": t, "motor_angle_rad": rev * 2 * math.pi / RATIO}, {"period_s": DT})
    s = usage_of_trace(tr)                               # 2 um hysteresis
    assert s.reversals == 10
    assert s.nut_travel_m == pytest.approx(20e-3, rel=2e-3)
    raw = usage_of_trace(tr, EXACT)                      # no hysteresis: noise counts
    assert raw.reversals > 500


def test_blocks_of_rows_equal_the_whole_trace():
    rng = np.random.default_rng(3)
    n = 4000
    t = np.arange(n) * DT
    cols = {"motor_angle_rad": 30 * np.sin(2 * math.pi * 1.5 * t) + rng.normal(0, 0.01, n),
            "position_m": 2e-3 * np.sin(2 * math.pi * 1.5 * t) + rng.normal(0, 2e-6, n),
            "load_force_n": 2000 * np.sin(2 * math.pi * 3 * t) + rng.normal(0, 2, n),
            "current_a": rng.normal(3, 1, n), "motor_speed_rad_s": rng.normal(0, 50, n),
            "winding_temperature_k": 290 + 40 * t}
    cols["load_force_n"][100:130] = np.nan               # a gap in the load cell
    whole = usage_of_trace(Trace({"t_s": t, **cols}, {"period_s": DT}))
    acc = UsageAccumulator(DT, Geometry.of(P0, UsageSettings()))
    for k in range(0, n, 37):
        acc.push({c: v[k:k + 37] for c, v in cols.items()})
    part = acc.summary()
    a, b = whole.as_dict(), part.as_dict()
    for key in a:
        assert a[key] == pytest.approx(b[key], rel=1e-9, abs=1e-12), key
    assert (whole.load_rainflow == part.load_rainflow).all()
    assert sum(v for k, v in a.items() if k.startswith("time_s_temp_")) == pytest.approx(4.0)
    assert a["dwell_s"] + a["slow_s"] + a["fast_s"] == pytest.approx(4.0)


def test_accumulate_per_actuator():
    steps = np.concatenate([[0.0], np.full(1000, 0.002)])
    one = usage_of_trace(trace_of(steps, np.full(1001, 3000.0)), EXACT, serial="7")
    two = usage_of_trace(trace_of(steps, np.full(1001, 6000.0)), EXACT, serial="7")
    other = usage_of_trace(trace_of(steps, np.full(1001, 1000.0)), EXACT, serial="9")
    acc = accumulate([one, other, two])
    assert list(acc) == ["7", "9"]
    a = acc["7"]
    assert a.runs == 2 and a.screw_revolutions == pytest.approx(4.0)
    assert a.life_consumed == pytest.approx(one.life_consumed + two.life_consumed, rel=1e-12)
    assert a.fm_n == pytest.approx(((3000.0 ** 3 + 6000.0 ** 3) / 2) ** (1 / 3), rel=1e-9)
    assert (a.load_spectrum_rev == one.load_spectrum_rev + two.load_spectrum_rev).all()
    flat = a.as_dict()
    assert all(isinstance(v, float) for v in flat.values())
    assert {"life_consumed", "fm_n", "l10_rev", "reversals", "i2t_a2s", "dwell_s"} <= set(flat)
    # the preload of a run does not matter without the double-nut treatment
    pre = usage_of_trace(trace_of(steps, np.full(1001, 3000.0)), EXACT, serial="7",
                         params=P0.with_dict({"effects.preload_n": 2000.0}))
    assert accumulate([one, pre])["7"].runs == 2
    other_ca = usage_of_trace(trace_of(steps, np.full(1001, 1000.0)), EXACT, serial="7",
                              params=P0.with_dict({"screw.dynamic_load_rating_n": 30000.0}))
    with pytest.raises(BenchError, match="does not add"):
        accumulate([one, other_ca])


def test_what_a_run_lacks_is_nan_not_zero_and_stays_so_when_accumulated():
    # quantities of an absent signal were 0 (I2t, life consumed, ...), and summed as such
    steps = np.concatenate([[0.0], np.full(1000, 0.002)])
    full = usage_of_trace(trace_of(steps, np.full(1001, 3000.0),
                                   current_a=np.full(1001, 2.0)), EXACT, serial="7")
    nocur = usage_of_trace(trace_of(steps, np.full(1001, 3000.0)), EXACT, serial="7")
    assert full.i2t_a2s == pytest.approx(4.0 * 1.001) and not full.not_available.get("i2t_a2s")
    assert math.isnan(nocur.i2t_a2s) and math.isnan(nocur.current_rms_a)
    assert nocur.not_available["i2t_a2s"] == "needs current_a"
    assert nocur.life_consumed == pytest.approx(full.life_consumed)     # has what it needs
    js = nocur.to_json()
    assert js["i2t_a2s"] is None and js["not_available"]["current_rms_a"] == "needs current_a"
    acc = accumulate([full, nocur])["7"]
    assert math.isnan(acc.i2t_a2s) and acc.life_consumed == pytest.approx(
        2 * full.life_consumed)
    # no motor angle: no revolutions, travel, reversals, nor the life they give
    pos = usage_of_trace(Trace({"t_s": np.arange(100) * DT, "position_m": np.zeros(100),
                                "load_force_n": np.full(100, 1e3)}, {"period_s": DT}))
    d = pos.as_dict()
    assert all(math.isnan(d[k]) for k in ("screw_revolutions", "nut_travel_m", "reversals",
                                          "life_consumed", "fm_n", "l10_rev"))
    assert pos.not_available["life_consumed"] == "needs motor_angle_rad"
    assert d["load_cycles"] == 0.0 and d["position_cycles"] == 0.0     # measured: none


def test_a_dwell_speed_above_the_fast_speed_is_refused():
    """dwell_speed_m_s above fast_speed_m_s counted a sample between them as both dwell
    and fast; it is refused, and a speed at an edge goes to the regime above it."""
    with pytest.raises(BenchError, match="dwell_speed_m_s 0.02 is above fast_speed_m_s 0.01"):
        UsageAccumulator(DT, Geometry.of(P0, UsageSettings()),
                         UsageSettings(dwell_speed_m_s=0.02, fast_speed_m_s=0.01))
