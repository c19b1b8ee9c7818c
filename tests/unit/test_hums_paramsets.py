"""The HUMS parameter sets (monitoring model, thesis monitor gains, lost-motion
kinematics) have the plant's treatment, the same defaults as before, and the spectra's
windows from scipy give the numbers of the periodic windows written out."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import windows

from bench.core.paramset import ParamSetError
from bench.hums import monitor as M
from bench.hums import spectra
from bench.hums.motion import Kinematics
from plant_rt.params import PlantParams


@pytest.mark.parametrize("cls", [M.MonitorParams, M.ThesisMonitorGains, Kinematics])
def test_every_parameter_has_unit_range_and_source(cls):
    for info in cls.infos():
        assert info.unit and info.source and info.doc, info.name
        assert info.min is not None and info.max is not None, info.name
        assert info.min <= info.default <= info.max, info.name
    p = cls()
    assert cls.from_json(p.to_json()) == p
    with pytest.raises(ParamSetError, match="unknown"):
        cls.from_dict({"no_such_parameter": 1.0})


def test_defaults_are_the_plant_derived_values_as_before():
    assert M.MonitorParams() == M.MonitorParams.from_plant(PlantParams())
    assert M.MonitorParams().friction_factor == 2.0 and M.MonitorParams().substep_s == 20e-6
    assert (M.THESIS_START_GAIN, M.THESIS_FITTED_GAIN) == (20.0, 663.0)
    assert Kinematics() == Kinematics.from_plant(PlantParams())
    assert Kinematics().travel_per_motor_rad_m == 0.25 * 5e-3 / (2 * math.pi)
    assert (Kinematics().lvdt_natural_rad_s, Kinematics().lvdt_damping) == (1256.0, 0.8)


def test_monitor_parameters_are_checked():
    with pytest.raises(ParamSetError, match="resistance_ohm"):
        M.MonitorParams.from_plant(resistance_ohm=math.nan)
    with pytest.raises(ParamSetError, match="lvdt_damping"):
        Kinematics(lvdt_damping=-1.0)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 8, 250, 499, 500, 1000, 2001, 120000])
def test_scipy_windows_give_the_periodic_windows(n):
    old_hann = (0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)) if n > 1 else np.ones(n)
    np.testing.assert_allclose(spectra._window("hann", n), old_hann, rtol=0, atol=2e-15)
    np.testing.assert_array_equal(spectra._window("rect", n), np.ones(n))
    np.testing.assert_array_equal(spectra._window("flattop", n), windows.flattop(n, sym=False))
