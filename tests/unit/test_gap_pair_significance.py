"""A pair whose added effect's 95 % interval holds that effect's no-effect value does not
replace the single (a delay-only log read as "delay + friction x0.99 [0.894, 1.10]"),
nor one whose added effect no signal shows above the floor (an encoder gain 0.97 read
with a friction x1.09): the rule in `diagnose._choose`, the interval test of
`finding.holds_no_effect` and the floor test of `finding.faint`."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np

from bench.gap import diagnose as D
from bench.gap import effects as E
from bench.gap import finding as FD
from bench.gap import resim as R
from bench.gap.fit import Fit
from plant_rt.params import PlantParams

SIG = dict.fromkeys(R.SIGNALS, 1.0)
P = NS(n=10000, n_fit=5000, info={})


def _cand(name: str, bic: float, excess: float, smooth: dict, insignificant=(),
          faint=()) -> NS:
    return NS(fit=NS(name=name, effects=tuple(name.split("+"))), bic=bic,
              heldout_excess=excess, heldout_smooth=smooth, suspect=[],
              insignificant=list(insignificant), faint=list(faint))


def test_a_pair_whose_added_effect_holds_no_effect_does_not_replace_the_single():
    single = _cand("sensor_delay", 0.0, 1.0, {**SIG, "position_m": 5.0})
    pair = _cand("sensor_delay+friction", -40.0, 0.2, SIG, insignificant=["friction"])
    chosen, verdict, _, _, sel = D._choose([single], [pair], single, P, None, 100.0, True, {})
    assert chosen is single and verdict == "sensor_delay"
    assert sel["pairs_rejected_as_insignificant"] == ["sensor_delay+friction"]
    pair.insignificant = []
    chosen, _, _, _, sel = D._choose([single], [pair], single, P, None, 100.0, True, {})
    assert chosen is pair and sel["pairs_rejected_as_insignificant"] == []


def test_the_next_pair_whose_added_effect_is_significant_may_still_replace_it():
    single = _cand("sensor_delay", 0.0, 1.0, {**SIG, "position_m": 5.0})
    null = _cand("sensor_delay+friction", -40.0, 0.2, SIG, insignificant=["friction"])
    other = _cand("sensor_delay+backlash", -20.0, 0.3, SIG)
    chosen, *_ = D._choose([single], [null, other], single, P, None, 100.0, True, {})
    assert chosen is other


def test_a_pair_whose_added_effect_is_below_the_floor_does_not_replace_the_single():
    single = _cand("encoder_gain", 0.0, 1.0, {**SIG, "motor_speed_rad_s": 5.0})
    faint = _cand("encoder_gain+friction", -40.0, 0.2, SIG, faint=["friction"])
    chosen, verdict, _, _, sel = D._choose([single], [faint], single, P, None, 100.0, True, {})
    assert chosen is single and verdict == "encoder_gain"
    assert sel["pairs_rejected_below_floor"] == ["encoder_gain+friction"]
    other = _cand("encoder_gain+backlash", -20.0, 0.3, SIG)
    chosen, _, _, _, sel = D._choose([single], [faint, other], single, P, None, 100.0, True, {})
    assert chosen is other and sel["pairs_rejected_below_floor"] == ["encoder_gain+friction"]
    # a pair the BIC margin refuses anyway is not simulated (its floor test never runs)
    late = _cand("encoder_gain+lead", -5.0, 0.2, SIG)
    late.faint = None
    chosen, _, _, _, sel = D._choose([single], [late], single, P, None, 100.0, True, {})
    assert chosen is single and late.faint is None and sel["pairs_rejected_below_floor"] == []


def _floor_problem(sigma: float) -> NS:
    """A problem whose re-simulation adds each effect's "x" to a constant current."""
    def simulate(objs, thetas):
        level = sum(th["x"] for th in thetas)
        return {"current_a": np.full(200, level), "position_m": np.zeros(200)}
    return NS(simulate=simulate, sigma={"current_a": sigma, "position_m": 1e-6})


def test_an_added_effect_is_faint_when_no_signal_moves_by_the_floor():
    f = NS(objs=[NS(name="encoder_gain"), NS(name="friction")],
           theta=[{"x": 3.0}, {"x": 0.05}])
    assert FD.faint(_floor_problem(0.1), f) == ["friction"]      # 0.05 of a floor 0.1
    assert FD.faint(_floor_problem(0.04), f) == []               # 1.25 floors
    f.theta[1]["x"] = -0.2                                         # either direction
    assert FD.faint(_floor_problem(0.1), f) == []
    # a re-simulation that fails judges nothing faint (the pair rule as without the clause)
    def broken(objs, thetas):
        raise FloatingPointError("overflow")
    assert FD.faint(NS(simulate=broken, sigma={"current_a": 1.0}), f) == []
    # the first effect is the single the pair extends: never judged
    assert FD.faint(_floor_problem(100.0), NS(objs=f.objs[:1], theta=f.theta[:1])) == []


def _fit(second: str, ci: tuple, at_bound: dict | None = None) -> Fit:
    objs = [E.get("sensor_delay"), E.get(second)]
    name = objs[1].params[0].name
    return Fit(("sensor_delay", second), [{"sensor_delay_s": 0.002}, {name: 0.5 * sum(ci)}],
               [{"sensor_delay_s": (0.002, 0.002)}, {name: ci}], 1.0, 100, 2, 1,
               objs=objs, at_bound=[{}, at_bound or {}])


def test_an_interval_holding_the_model_value_is_no_effect():
    p = NS(base=PlantParams())
    assert FD.insignificant(p, _fit("lvdt_offset", (-2e-5, 4e-5))) == ["lvdt_offset"]
    assert FD.insignificant(p, _fit("lvdt_offset", (5e-6, 4e-5))) == []
    # a backlash on its upper bound: open above, its lower end above zero
    assert FD.insignificant(p, _fit("backlash", (2.8e-4, 3e-4), {"backlash_m": "upper"})) == []
    assert FD.insignificant(p, _fit("backlash", (0.0, 3e-5))) == ["backlash"]


def test_a_friction_member_is_judged_by_its_growth_factor(monkeypatch):
    p = NS(base=PlantParams())
    f = _fit("friction", (0.95, 1.02))       # the parameter's interval alone holds 1
    monkeypatch.setattr(FD, "friction_size", lambda p, f, i: {"factor": 1.2,
                                                               "ci95": [1.05, 1.3]})
    assert FD.insignificant(p, f) == []
    monkeypatch.setattr(FD, "friction_size", lambda p, f, i: {"factor": 0.99,
                                                               "ci95": [0.894, 1.10]})
    assert FD.insignificant(p, f) == ["friction"]


def test_a_pair_whose_verdict_interval_holds_no_effect_gives_way(monkeypatch):
    """The fast fit's interval left the friction apart from 1, the verdict's (refined)
    interval holds it: the single is taken, and the pair recorded."""
    single = _cand("sensor_delay", 0.0, 1.0, {**SIG, "position_m": 5.0})
    pair = _cand("sensor_delay+friction", -40.0, 0.2, SIG)
    for c in (single, pair):
        c.fit.rss = 1.0
    refined = []
    monkeypatch.setattr(D, "refine", lambda p, f: (refined.append(f.name) or f, {}))
    monkeypatch.setattr(D, "_model_form", lambda p, f, *a: f)
    monkeypatch.setattr(D, "_settle_alias", lambda p, h, L, c, s, v, r, t, *a: (c, v, r, t))
    monkeypatch.setattr(D, "insignificant", lambda p, f: ["friction"] if "+" in f.name else [])
    loc: dict = {}
    o = D.Options()
    chosen, verdict, _, _ = D._verdict(P, None, 1.0, o, (None, 0.5), ([single], [pair], single),
                                       (True, 100.0, None), loc, lambda s: None)
    assert chosen is single and verdict == "sensor_delay"
    assert refined == ["sensor_delay+friction", "sensor_delay"]
    assert loc["selection"]["pairs_rejected_as_insignificant"] == ["sensor_delay+friction"]
