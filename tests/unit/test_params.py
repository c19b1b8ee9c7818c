"""Parameter sets: validation with clear errors, JSON round trip, flat names."""

from __future__ import annotations

import math

import pytest

from plant_rt.params import PARAMS, MotorParams, ParameterError, PlantParams, ScrewParams, resolve


def test_defaults_are_the_thesis_tables():
    p = PlantParams()
    assert p.motor.resistance_ohm == 0.4 and p.motor.kt_nm_per_a == 1.5     # table 5.2
    assert p.reducer.ratio == 0.25 and p.reducer.efficiency == 0.95          # table 5.3
    assert p.screw.lead_m == 5e-3 and p.screw.balls_active == 21             # table 5.4
    assert p.sensors.lvdt_natural_rad_s == 1256.0                            # table 5.1
    assert p.screw.stiffness_preload_slope_per_m == 820.5                    # eq. 5.21


@pytest.mark.parametrize("assignment, fragment", [
    ("motor.resistance_ohm=nan", "motor.resistance_ohm: NaN"),
    ("screw.nut_mass_kg=-1", "screw.nut_mass_kg = -1 kg is below its minimum"),
    ("backlash_m=-1e-6", "effects.backlash_m = -1e-06 m is below its minimum"),
    ("no_such_thing=3", "unknown parameter 'no_such_thing'"),
    ("drive.pwm_mode=pulsed", "drive.pwm_mode: expected one of switching, averaged"),
    ("sensors.noise=maybe", "sensors.noise: expected on/off"),
    ("screw.balls_active=2.5", "screw.balls_active: expected an integer"),
    ("effects.preload_n=inf", "effects.preload_n: 'inf' is not finite"),
    ("backlash_m", "--set expects NAME=VALUE"),
])
def test_bad_values_are_rejected_naming_the_parameter(assignment, fragment):
    with pytest.raises(ParameterError) as exc:
        PlantParams().with_assignments([assignment])
    assert fragment in str(exc.value)


def test_direct_construction_is_validated():
    with pytest.raises(ParameterError, match="motor.inductance_h"):
        MotorParams(inductance_h=float("nan"))
    with pytest.raises(ParameterError, match="screw.nut_mass_kg"):
        ScrewParams(nut_mass_kg=-0.1)


def test_json_round_trip_and_diff():
    p = PlantParams().with_assignments(["backlash_m=5e-5", "sensors.noise=on",
                                        "load.kind=sine"])
    q = PlantParams.from_json(p.to_json())
    assert q.diff(p) == {}
    d = PlantParams().diff(p)
    assert set(d) == {"effects.backlash_m", "sensors.noise", "load.kind"}
    assert d["effects.backlash_m"] == (0.0, 5e-5)
    assert math.isnan(q.screw.reaction_lever_m)  # NaN survives as "use eq. 5.10"


def test_from_json_rejects_unknown_group_and_bad_json():
    with pytest.raises(ParameterError, match="unknown parameter group"):
        PlantParams.from_json('{"motr": {"resistance_ohm": 1}}')
    with pytest.raises(ParameterError, match="not valid JSON"):
        PlantParams.from_json("{oops")


def test_every_parameter_has_unit_range_doc_and_source():
    assert len(PARAMS) > 60
    for info in PARAMS:
        assert info.unit and info.doc and info.source, info.name
        assert resolve(info.name) is info
        if info.type in (int, float):
            assert info.min is not None and info.max is not None and info.min <= info.max
            if not (isinstance(info.default, float) and math.isnan(info.default)):
                assert info.min <= info.default <= info.max, info.name
