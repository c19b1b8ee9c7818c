"""The ECU controller's parameter set has the plant's treatment: units, ranges, sources,
validation, diff, JSON round trip, unknown names refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import BenchError
from bench.sim.control import ControllerParams, position_gain_for_bandwidth
from plant_rt.params import THESIS, ParameterError


def test_defaults_and_vector_unchanged():
    cp = ControllerParams()
    kp = 2 * math.pi * 6.0 / (0.25 * 5e-3 / (2 * math.pi))
    np.testing.assert_array_equal(cp.vector(), [kp, 0.5, 12.0, 251.0, 25.0, 1e-3])
    assert position_gain_for_bandwidth(6.0) == kp
    assert position_gain_for_bandwidth(6.0, THESIS.reducer.ratio, THESIS.screw.lead_m) == kp


def test_every_parameter_has_unit_range_source_and_doc():
    infos = ControllerParams.infos()
    assert [i.leaf for i in infos] == list(ControllerParams().to_dict())
    for i in infos:
        assert i.name == f"controller.{i.leaf}"
        assert i.unit and i.doc and i.source and i.type is float
        assert i.min is not None and i.max is not None and i.min <= i.default <= i.max


def test_json_round_trip_and_diff():
    cp = ControllerParams(speed_kp_a_s_per_rad=0.7)
    back = ControllerParams.from_json(cp.to_json())
    assert back == cp
    assert cp.diff(ControllerParams()) == {"controller.speed_kp_a_s_per_rad": (0.7, 0.5)}
    assert cp.with_values(speed_kp_a_s_per_rad=0.5) == ControllerParams()
    assert ControllerParams.from_dict({"controller.current_limit_a": 10}).current_limit_a == 10.0


@pytest.mark.parametrize("bad", [{"speed_gain": 1.0}, {"controller.nope": 1.0}])
def test_unknown_names_are_refused(bad):
    with pytest.raises(ParameterError, match="unknown controller parameter"):
        ControllerParams.from_dict(bad)


@pytest.mark.parametrize("kw", [{"current_limit_a": -1.0}, {"speed_ki_a_per_rad": math.nan},
                                {"sample_period_s": 0.0}, {"speed_limit_rad_s": math.inf},
                                {"speed_kp_a_s_per_rad": "fast"}])
def test_invalid_values_name_the_parameter(kw):
    name = next(iter(kw))
    with pytest.raises(BenchError, match=f"controller.{name}"):
        ControllerParams(**kw)
    with pytest.raises(ParameterError):
        ControllerParams(**kw)
