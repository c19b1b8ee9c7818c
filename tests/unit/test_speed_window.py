"""The encoder speed estimator as a sensor property (`sensors.encoder_speed_window`)."""

import math

import numpy as np
import pytest

from bench.gap import resim as R
from bench.rig.actuator import from_dict, sensor_params
from plant_rt import kernel as K
from plant_rt.model import Plant
from plant_rt.params import ParameterError, PlantParams

FAST = PlantParams().with_dict({**R.FAST, "sensors.noise": False})


def _run(plant: Plant, n: int) -> np.ndarray:
    rows = []
    for k in range(n):
        rows.append(plant.measure()[:4])
        plant.step(4.0 * math.sin(k / 15.0))
    return np.array(rows)


def test_default_is_the_filter_and_ignores_the_history():
    """Window 0 (default): the speed is the eq. 5.1 filter state; the angle history the
    kernel keeps for a window never reaches an output (scrambled, nothing changes)."""
    assert PlantParams().sensors.encoder_speed_window == 0
    a, b = Plant(FAST), Plant(FAST)
    b.x[K.TH_HIST:] = np.random.default_rng(3).normal(size=K.NHIST) * 50.0
    ya, yb = _run(a, 60), _run(b, 60)
    np.testing.assert_array_equal(ya, yb)
    np.testing.assert_array_equal(a.x[:K.TH_HIST], b.x[:K.TH_HIST])
    m = a.measure()
    assert m.motor_speed_rad_s == a.x[K.EY]


@pytest.mark.parametrize("win", [1, 4, 16])
def test_window_is_the_count_difference(win):
    """Window N: (theta_q[k] - theta_q[k - N]) / (N T) of the logged (quantised) angles."""
    pp = FAST.with_dict({"sensors.encoder_speed_window": win})
    y = _run(Plant(pp), 80)
    ang, spd = y[:, 2], y[:, 1]
    t = pp.sim.sync_period_s
    np.testing.assert_allclose(spd[win:], (ang[win:] - ang[:-win]) / (win * t),
                               rtol=0, atol=1e-9)
    assert np.all(spd[:win] == (ang[:win] - ang[0]) / (win * t))   # at rest before t = 0
    # the model's offline sensor path agrees
    np.testing.assert_allclose(R.encoder_speed_from_angle(ang, pp, t), spd, atol=1e-9)


def test_window_range_is_checked():
    with pytest.raises(ParameterError):
        PlantParams().with_dict({"sensors.encoder_speed_window": K.NHIST + 1})


def test_actuator_description_gives_the_window():
    a = from_dict({"motor_kind": "bldc_current_loop", "encoder_speed_window_periods": 4})
    assert sensor_params(a) == {"sensors.encoder_speed_window": 4}
    assert sensor_params(from_dict({"motor_kind": "bldc_current_loop"})) == {}
