"""What the diagnosis prints is sorted by the criterion it names, and fits report their
own trouble: a parameter on its bound (no degenerate interval), a value no wear or build
error makes (suspect; such a pair does not replace the single), dimensionless values
without a unit mark."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
import pytest

from bench.gap import families as F
from bench.gap import resim as R
from bench.gap.summary import fmt_params, fmt_value

SIG = dict.fromkeys(R.SIGNALS, 1.0)


def _cand(name: str, bic: float, excess: float, smooth: dict, suspect=()) -> NS:
    return NS(fit=NS(name=name, effects=tuple(name.split("+"))), bic=bic,
              heldout_excess=excess, heldout_smooth=smooth, suspect=list(suspect),
              faint=[])                 # shown above the floor (its test: test_gap_pair_significance)


def test_ranking_is_sorted_by_bic_with_the_chosen_one_marked():
    """A single that leaves no significant held-out gap is chosen over a pair of lower BIC;
    the ranking still lists the pair first (before: the chosen one first, so the table
    under "BIC, lower is better" read 207.6 above 159.0)."""
    from bench.gap import diagnose as D
    single = _cand("backlash", 207.6, 1.0, SIG)
    pair = _cand("backlash+lead", 159.0, 0.9, SIG)
    p = NS(n=10000, n_fit=5000, info={})
    chosen, verdict, ranking, _, _ = D._choose([single], [pair], single, p, None, 100.0,
                                               True, {})
    assert chosen is single and verdict == "backlash"
    assert [c.bic for c in ranking] == [159.0, 207.6]


def test_a_suspect_pair_does_not_replace_the_single():
    from bench.gap import diagnose as D
    single = _cand("backlash", 0.0, 1.0, {**SIG, "encoder_position_m": 5.0})
    pair = _cand("backlash+friction", -80.0, 0.1, SIG,
                 suspect=["friction_scale x0.2 of the model's: lower than any wear makes it"])
    p = NS(n=10000, n_fit=5000, info={})
    chosen, _, _, _, sel = D._choose([single], [pair], single, p, None, 100.0, True, {})
    assert chosen is single
    assert sel["pairs_rejected_as_suspect"] == ["backlash+friction"]
    pair.suspect = []
    assert D._choose([single], [pair], single, p, None, 100.0, True, {})[0] is pair


def test_suspect_values():
    line, = F.suspect({"friction_scale": {"value": 0.2, "unit": "-"}}, {"friction_scale": 1.0})
    assert line.startswith("friction_scale x0.2 of the model's: lower than any wear")
    assert F.suspect({"friction_scale": {"value": 2.5}}, {"friction_scale": 1.0}) == []
    assert F.suspect({"preload_n": {"value": 900.0}}, {"preload_n": 0.0}) == []   # no nominal
    assert F.suspect({"lead_m": {"value": 5.3e-3}}, {"lead_m": 5e-3})
    off = F.suspect({"current_offset_a": {"value": 1.5, "unit": "A"}}, {"current_offset_a": 0})
    assert off and "zero tolerance" in off[0]


def test_dimensionless_values_have_no_unit_mark_and_bounds_no_degenerate_interval():
    assert fmt_value(2.281, "-") == "2.281"
    text = fmt_params({"friction_scale": {"value": 2.281, "ci95": [2.221, 2.343], "unit": "-"}})
    assert text == "friction_scale = 2.281 [2.221, 2.343]"
    edge = fmt_params({"backlash_m": {"value": 300e-6, "ci95": [287e-6, None], "unit": "m",
                                      "at_bound": "upper"}})
    assert edge == "backlash_m = 300 um [287, bound] (at its upper bound)"
    assert "[300, 300]" not in edge


def test_a_fit_beyond_its_bound_is_flagged(tmp_path):
    """400 um of backlash against a family bounded at 300 um: the fit ends on the bound,
    says so, and its interval is open on that side."""
    from bench.gap.fit import fit
    from bench.gap.problem import build
    from bench.profiles.maneuvers import compact
    from bench.sim.harness import simulate
    from plant_rt.params import PlantParams
    base = PlantParams().with_dict({**R.FAST, "sensors.noise": True, "sensors.noise_seed": 2})
    log = simulate(compact(), base.with_dict({"effects.backlash_m": 400e-6})).measured()
    p = build(log, PlantParams(), 0.5, bootstrap=2, model_floor=False)
    f = fit(p, ["backlash"])
    assert f.at_bound == [{"backlash_m": "upper"}]
    d = f.params_dict()["backlash_m"]
    assert d["at_bound"] == "upper" and d["ci95"][1] is None
    assert d["value"] == pytest.approx(300e-6, rel=1e-3)
    assert np.isfinite(d["ci95"][0]) and d["ci95"][0] < 300e-6


def test_the_pair_rule_counts_the_excess_above_the_calibrations_healthy_energy():
    """Against a calibration whose model leaves some misfit on a healthy log, a pair that
    removes most of what the single leaves above that healthy energy replaces it, though
    it removes less than half of the whole excess (the healthy misfit stays in both).
    Before, the rule counted the whole excess and kept the single: backlash 40 um and
    friction x2 on the independent actuator read as backlash alone, BIC 517 against the
    pair's 130."""
    from bench.gap import diagnose as D
    healthy = {"current_a": 2.0, "motor_speed_rad_s": 20.0, "position_m": 6.0,
               "encoder_position_m": 2.0}
    ref = {"energy": healthy, "level": None, "margin": None}
    single = _cand("backlash", 517.0, 0.0, {**SIG, "encoder_position_m": 9.0})
    single.heldout = {**healthy, "encoder_position_m": 23.0}        # 21 above healthy
    pair = _cand("backlash+friction", 130.0, 0.0, SIG)
    pair.heldout = {**healthy, "encoder_position_m": 11.5}          # 9.5 above healthy
    single.heldout_excess = sum(v - 1 for v in single.heldout.values())
    pair.heldout_excess = sum(v - 1 for v in pair.heldout.values())
    assert pair.heldout_excess > 0.5 * single.heldout_excess          # the whole excess
    p = NS(n=10000, n_fit=5000, info={})
    before = {**healthy, "encoder_position_m": 2400.0}
    chosen = D._choose([single], [pair], single, p, None, 2400.0, True, {}, ref, before)[0]
    assert chosen is pair


def test_a_suspect_single_gives_way_to_a_plausible_one_as_good():
    from bench.gap import diagnose as D
    lead = _cand("lead", -93.9, 0.1, SIG, suspect=["lead_m x1.05 of the model's: beyond "
                                                   "any screw's lead tolerance"])
    gain = _cand("lvdt_gain", -92.0, 0.1, SIG)
    p = NS(n=10000, n_fit=5000, info={})
    chosen, verdict, ranking, _, _ = D._choose([lead, gain], [], lead, p, None, 100.0, True,
                                               {})
    assert chosen is gain and verdict == "lvdt_gain"
    assert ranking[0] is lead                      # the table stays in BIC order
    far = _cand("lvdt_gain", -60.0, 0.1, SIG)     # 34 worse: the suspect one stays
    assert D._choose([lead, far], [], lead, p, None, 100.0, True, {})[0] is lead
