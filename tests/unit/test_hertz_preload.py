"""The Hertzian preload law of the double nut (`screw.hertz_reference_preload_n`), the
catalogue preload drag of the independent actuator's datasheet model, and the library's
LVDT lag in the loop when the model's LVDT conditioner is first order (indie6)."""

import math

import numpy as np
import pytest

from bench.gap import effects as E
from bench.gap import resim as R
from bench.gap.indiebench import (
    NOMINAL,
    catalogue_preload_drag_nm,
    datasheet_model,
    rolling_friction_for_drag,
)
from plant_rt import kernel as K
from plant_rt.contacts import hertz_share, hertz_stiffness_ratio, normal_to_axis
from plant_rt.model import Plant, param_vector
from plant_rt.params import PlantParams

FAST = PlantParams().with_dict({**R.FAST, "sensors.noise": False, "effects.preload_n": 1500.0,
                                "load.kind": "sine", "load.amplitude_n": 2000.0,
                                "load.frequency_hz": 20.0})


@pytest.mark.parametrize("q", [1e-4, 0.3, 1.0, 2.0, 2.8, 2.9, 7.0])
def test_share_solves_the_hertzian_double_nut(q):
    s = hertz_share(q)
    got = (1 + s) ** 1.5 - max(1 - s, 0.0) ** 1.5
    assert got == pytest.approx(q, rel=1e-9)


def test_ratio_one_at_reference_tangent_at_small_loads_softer_with_less_preload():
    for f in (0.0, 1e-3, 300.0, 2000.0, 9000.0):
        assert hertz_stiffness_ratio(f, 1500.0, 1500.0) == 1.0
    assert hertz_stiffness_ratio(1.0, 500.0, 1500.0) == pytest.approx((1 / 3) ** (1 / 3),
                                                                       rel=1e-3)
    r = [hertz_stiffness_ratio(2000.0, fpr, 1500.0) for fpr in (0.0, 250.0, 750.0, 1500.0)]
    assert r == sorted(r) and r[0] > 0.2 and r[-1] == 1.0
    for f, fpr in ((0.0, 700.0), (1500.0, 300.0), (3000.0, 4000.0)):     # compiled = Python
        assert K._hertz_ratio(f, fpr, 1500.0) == pytest.approx(
            hertz_stiffness_ratio(f, fpr, 1500.0), rel=1e-14)


def _travel(params: PlantParams, n: int = 80) -> np.ndarray:
    plant = Plant(params)
    out = []
    for k in range(n):
        plant.step(3.0 * math.sin(k / 10.0))
        # the nut's deflection from the screw (axial), and the screw speed
        out.append([0.5 * (plant.x[K.X1] + plant.x[K.X2])
                    - plant.x[K.TH] * params.screw.lead_m / (2 * math.pi), plant.x[K.OM]])
    return np.array(out)


def test_law_off_by_default_and_identical_at_the_reference_preload():
    assert PlantParams().screw.hertz_reference_preload_n == 0.0
    assert param_vector(PlantParams())[K.P_HREF] == 0.0
    base = _travel(FAST)
    on = FAST.with_dict({"screw.hertz_reference_preload_n": 1500.0})
    np.testing.assert_array_equal(_travel(on), base)
    # a preload loss now softens the nut under the 2 kN load (eq. 5.21 alone: ~1 %)
    lost = _travel(on.with_dict({"effects.preload_n": 300.0}))
    lost_linear = _travel(FAST.with_dict({"effects.preload_n": 300.0}))
    assert np.all(np.isfinite(lost))
    assert np.max(np.abs(lost[:, 0] - base[:, 0])) > 5 * np.max(
        np.abs(lost_linear[:, 0] - base[:, 0]))


def test_datasheet_model_declares_the_preload_law_and_the_catalogue_drag():
    m = datasheet_model(preload_law="hertz-fv")
    assert m.screw.hertz_reference_preload_n == NOMINAL.preload_n
    assert datasheet_model(preload_law="none").screw.hertz_reference_preload_n == 0.0
    drag = catalogue_preload_drag_nm()
    assert 0.1 < drag < 0.3          # N m at the screw, 1.5 kN on a 16 x 4 mm nut
    d = datasheet_model(preload_law="hertz-drag")    # the drag as a screw torque per N
    assert d.screw.preload_drag_nm_per_n * NOMINAL.preload_n == pytest.approx(drag)
    assert d.screw.rolling_friction == PlantParams().screw.rolling_friction
    h = datasheet_model()            # the default: the Hertzian law, the thesis' drag
    assert h.screw.hertz_reference_preload_n == NOMINAL.preload_n
    assert h.screw.preload_drag_nm_per_n == 0.0
    assert h.screw.rolling_friction == PlantParams().screw.rolling_friction
    with pytest.raises(ValueError):
        datasheet_model(preload_law="linear")
    s = m.screw
    lever = math.cos(math.radians(s.helix_angle_deg)) * s.lever_m + s.lead_m / (2 * math.pi)
    model_drag = s.rolling_friction * 2 * m.effects.preload_n / normal_to_axis(m) * lever
    assert model_drag == pytest.approx(drag, rel=1e-12)
    assert rolling_friction_for_drag(m, drag) == pytest.approx(s.rolling_friction)


def test_lvdt_lag_in_the_loop_when_the_conditioner_is_first_order():
    eff = E.get("lvdt_lag")
    thesis = PlantParams()
    assert eff.in_log(thesis) and eff.plant_overrides({"lvdt_lag_s": 0.004}, thesis) == {}
    first = thesis.with_dict({"sensors.lvdt_time_constant_s": 1e-3})
    assert not eff.in_log(first)
    over = eff.plant_overrides({"lvdt_lag_s": 0.004}, first)
    assert over == {"sensors.lvdt_time_constant_s": pytest.approx(0.005)}
    assert eff.plant_overrides({"lvdt_lag_s": 0.0}, first) == {
        "sensors.lvdt_time_constant_s": 1e-3}
    for name in E.names():       # every other effect keeps its declared place
        if name != "lvdt_lag":
            assert E.get(name).in_log(first) == (E.get(name).where == "log")


def test_preload_drag_off_by_default_and_a_torque_per_newton_of_preload():
    assert PlantParams().screw.preload_drag_nm_per_n == 0.0
    assert param_vector(PlantParams())[K.P_PDRAG] == 0.0
    base = _travel(FAST)
    drag = _travel(FAST.with_dict({"screw.preload_drag_nm_per_n": 1e-4}))
    lost = _travel(FAST.with_dict({"screw.preload_drag_nm_per_n": 1e-4,
                                   "effects.preload_n": 0.0}))
    no_preload = _travel(FAST.with_dict({"effects.preload_n": 0.0}))
    speed = [float(np.sum(np.abs(r[:, 1]))) for r in (base, drag)]
    assert speed[1] < speed[0]           # 0.15 N m more friction at the screw
    np.testing.assert_array_equal(lost, no_preload)     # no preload, no drag
