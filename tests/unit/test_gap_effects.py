"""The candidate-effect library: lazy registry, units and bounds, parameter scales."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import BenchError
from bench.gap import effects as E
from bench.gap.effects import Effect, Param
from plant_rt.params import PlantParams, resolve

REQUIRED = {"backlash", "friction", "viscous", "stribeck", "stiffness", "preload",
            "sensor_delay", "lvdt_lag", "lvdt_gain", "lvdt_offset", "encoder_gain",
            "current_offset", "resistance", "thermal_drift", "kt", "inertia", "lead"}


def test_library_covers_the_issue_and_every_parameter_has_unit_and_bounds():
    assert REQUIRED <= set(E.names())
    base = PlantParams()
    for name in E.names():
        eff = E.get(name)
        assert eff.params and eff.doc and eff.where in ("plant", "log")
        nom = eff.nominal(base)
        for p in eff.params:
            assert p.unit and p.lo < p.hi, (name, p)
            assert p.lo <= nom[p.name] <= p.hi or name == "viscous", (name, p.name)
        over = eff.plant_overrides({p.name: p.from_unit(0.5) for p in eff.params}, base)
        for k in over:
            resolve(k)                       # real plant parameter names
        base.with_dict(over)                 # within the plant's own ranges


def test_unknown_effect_is_a_clear_error():
    with pytest.raises(BenchError, match="unknown effect 'ripple'.*known: backlash"):
        E.get("ripple")
    with pytest.raises(BenchError, match="unknown effect"):
        E.parse_list("backlash,ripple")
    assert E.parse_list("kt, kt ,lead") == ["kt", "lead"]


class Bump(Effect):
    name = "bump"
    doc = "test effect"
    params = (Param("bump_a", "A", 0.0, 1.0, "amplitude"),)
    where = "log"

    def nominal(self, base):
        return {"bump_a": 0.0}


def test_register_is_lazy_and_checked():
    E.register("bump", __name__, "Bump")
    try:
        assert E.get("bump").params[0].unit == "A"
        E.register("notaneffect", "math", "pi")
        with pytest.raises(BenchError, match="cannot be loaded|not a bench.gap Effect"):
            E.get("notaneffect")
    finally:
        E.EFFECTS.pop("bump", None)
        E.EFFECTS.pop("notaneffect", None)


@pytest.mark.parametrize("p", [Param("a", "m", 0.0, 3e-4, ""), Param("b", "-", 0.2, 8.0, "", log=True)])
def test_unit_coordinates_round_trip(p):
    for u in np.linspace(0, 1, 7):
        assert p.to_unit(p.from_unit(u)) == pytest.approx(u, abs=1e-12)
    assert p.from_unit(-1.0) == p.lo and p.from_unit(2.0) == pytest.approx(p.hi)
    h = 1e-6
    num = (p.from_unit(0.3 + h) - p.from_unit(0.3 - h)) / (2 * h)
    assert p.dvalue_du(0.3) == pytest.approx(num, rel=1e-5)


def test_discrete_grid_is_whole_periods():
    g = E.get("sensor_delay").params[0].grid()
    assert g[0] == 0.0 and math.isclose(g[1], 1e-3) and math.isclose(g[-1], 8e-3)


def test_log_side_effects_act_on_logged_columns_only():
    cols = {"current_a": np.arange(10.0), "position_m": np.r_[np.zeros(5), np.ones(5)],
            "motor_speed_rad_s": np.zeros(10), "motor_angle_rad": np.zeros(10),
            "current_demand_a": np.arange(10.0)}
    lag = E.get("lvdt_lag").post(cols, {"lvdt_lag_s": 0.005}, 1e-3)
    assert lag["position_m"][5] < 0.5 and lag["position_m"][-1] > 0.5
    sk = E.get("log_skew").post(cols, {"log_skew_s": 0.002}, 1e-3)
    np.testing.assert_array_equal(sk["current_a"][2:], cols["current_a"][:-2])
    np.testing.assert_array_equal(sk["current_demand_a"], cols["current_demand_a"])


def test_bounds_follow_the_actuators_own_nominal():
    """The library's lead, inertia, kt and resistance bounds are a range around the
    thesis' actuator: a 10 mm lead or a 1e-5 kg m^2 rotor was outside them. Such a value
    now moves the range to it; a value inside keeps it (the thesis' model, and the
    independent actuator's 4 mm lead on the lower bound: docs/gap.md says why). The
    library's ranges are scaled to any model's value, so the 4 mm lead's
    `lead` candidate can also shorten it; the calibration keeps the range that contains
    the value (`test_calibration_bounds_contain_another_actuators_nominal`)."""
    from bench.gap.candidate import bound_scale
    from plant_rt.params import PlantParams
    thesis = PlantParams()
    for name in ("lead", "inertia", "kt", "resistance"):
        assert E.get(name).for_model(thesis) is E.get(name)
    assert bound_scale(thesis, "screw.lead_m") == 1.0
    edge = thesis.with_dict({"screw.lead_m": 4e-3})
    on_edge = E.get("lead").for_model(edge).params[0]
    assert on_edge.lo < 4e-3 * 0.99 and on_edge.hi > 4e-3 * 1.01
    other = thesis.with_dict({"screw.lead_m": 10e-3, "motor.inertia_kg_m2": 1e-5})
    lead = E.get("lead").for_model(other).params[0]
    assert lead.lo < 10e-3 * 0.99 and lead.hi > 10e-3 * 1.01
    assert lead.to_unit(10e-3) == pytest.approx(E.get("lead").params[0].to_unit(5e-3))
    inertia = E.get("inertia").for_model(other).params[0]
    assert inertia.lo < 1e-5 < inertia.hi
    assert E.get("friction").for_model(other) is E.get("friction")    # a scale already
    assert E.get("lead").params[0].lo == 4e-3                         # the class untouched


def test_calibration_bounds_contain_another_actuators_nominal():
    """`bench calibrate` clipped a 10 mm lead into 4-6 mm (start and prior)."""
    from bench.gap.calibrate import PlantSet, _prior
    from plant_rt.params import PlantParams
    base = PlantParams().with_dict({"screw.lead_m": 10e-3, "motor.kt_nm_per_a": 0.1})
    eff = PlantSet(["screw.lead_m", "motor.kt_nm_per_a", "sensors.lvdt_gain"], base)
    b = {p.name: (p.lo, p.hi) for p in eff.params}
    assert b["screw.lead_m"][0] < 10e-3 < b["screw.lead_m"][1]
    assert b["motor.kt_nm_per_a"][0] < 0.1 < b["motor.kt_nm_per_a"][1]
    assert b["sensors.lvdt_gain"] == (0.8, 1.25)                      # a ratio: unchanged
    prior = _prior(eff, eff.nominal(base))
    assert prior["screw.lead_m"][0] == 10e-3 and prior["motor.kt_nm_per_a"][0] == 0.1
    same = PlantSet(["screw.lead_m"], PlantParams()).params[0]
    assert (same.lo, same.hi) == (4e-3, 6e-3)
    # a value on the edge of the thesis' range: scaled too, so it can move both ways (the
    # independent actuator's 4 mm lead sat on the 4-6 mm range's lower bound and could
    # only grow: its calibration's interval read [4.000, 4.016] mm)
    edge = PlantSet(["screw.lead_m"], PlantParams().with_dict({"screw.lead_m": 4e-3}))
    lo, hi = edge.params[0].lo, edge.params[0].hi
    assert lo == pytest.approx(3.2e-3) and hi == pytest.approx(4.8e-3)


def test_preload_loss_gets_start_points_below_the_nominal():
    """A preload is lost with wear: its fit also starts at 0.5 and 0.1 x the nominal
    (docs/gap.md, "Candidate effects and their families"), the generic start points kept in order."""
    eff = E.get("preload")
    assert eff.wear_direction == "down"
    base = PlantParams().with_dict({"effects.preload_n": 1500.0})
    pts = [sp["preload_n"] for sp in eff.start_points(base)]
    # what any effect gets: the nominal + 0.05 of the range, then 0.15, 0.5, 0.85 of it
    assert pts[:4] == pytest.approx([1900.0, 1200.0, 4000.0, 6800.0])
    assert pts[4:] == pytest.approx([750.0, 150.0])
    assert min(pts) < 0.5 * 1500.0
    # a nominal of 0 (the bench's own plant) has no loss to start from: nothing added
    assert [sp["preload_n"] for sp in eff.start_points(PlantParams())] == \
        pytest.approx([400.0, 1200.0, 4000.0, 6800.0])
    # no other effect declares a wear direction (this task adds it to preload only)
    assert [n for n in E.names() if E.get(n).wear_direction is not None] == ["preload"]


def test_a_drive_whose_current_pi_follows_its_winding():
    """`drive.current_pi_follows_winding` (off by default: the thesis' fixed gains, the
    kernel's vector unchanged): on, the integral gain is kp R / L of the model's winding,
    so a resistance candidate moves it. The independent actuator's datasheet model
    declares it, with the same gains as before at its datasheet R."""
    from bench.gap.indiebench import datasheet_model
    from plant_rt import kernel as K
    from plant_rt.model import param_vector
    thesis = PlantParams()
    assert param_vector(thesis)[K.P_KII] == thesis.drive.current_ki_v_per_as
    on = thesis.with_dict({"drive.current_pi_follows_winding": True,
                           "motor.resistance_ohm": 0.8})
    assert param_vector(on)[K.P_KII] == pytest.approx(
        thesis.drive.current_kp_v_per_a * 0.8 / thesis.motor.inductance_h)
    ds = datasheet_model()
    assert ds.drive.current_pi_follows_winding
    assert param_vector(ds)[K.P_KII] == pytest.approx(ds.drive.current_ki_v_per_as)


def test_bounds_follow_the_model_once_whatever_the_copy():
    """A fitted candidate's effect, already moved to its model, refitted on that model
    (the verdict's refit against the full-fidelity model) keeps the same range: before,
    its range was scaled a second time, 2.56-3.84 mm for a 4 mm model, and the refit of
    an LVDT gain's 4.12 mm alias ended on that bound at 3.84 mm."""
    from plant_rt.params import PlantParams
    four = PlantParams().with_dict({"screw.lead_m": 4e-3})
    once = E.get("lead").for_model(four)
    twice = once.for_model(four)
    assert (twice.params[0].lo, twice.params[0].hi) == (once.params[0].lo, once.params[0].hi)
    assert once.params[0].lo == pytest.approx(3.2e-3) and once.params[0].hi == pytest.approx(4.8e-3)
    assert E.get("lead").for_model(PlantParams()) is E.get("lead")
