"""A double nut preloaded by an interference that a wear clearance eats first
(`screw.preload_by_interference`, `plant_rt.contacts.worn_nut`; docs/gap.md, "The verdict in words")."""

import math

import numpy as np
import pytest

from bench.gap import resim as R
from bench.gap.indiebench import datasheet_model
from plant_rt import kernel as K
from plant_rt.contacts import contact_geometry, worn_nut
from plant_rt.model import Plant, effects_at, param_vector
from plant_rt.params import PlantParams
from plant_rt.wear import interference_from_preload

FAST = PlantParams().with_dict({**R.FAST, "sensors.noise": False, "effects.preload_n": 1500.0,
                                "load.kind": "sine", "load.amplitude_n": 2000.0,
                                "load.frequency_hz": 20.0})


def test_off_by_default_and_declared_by_the_independent_datasheet_model():
    assert PlantParams().screw.preload_by_interference is False
    assert param_vector(PlantParams())[K.P_INTERF] == 0.0
    assert datasheet_model().screw.preload_by_interference is True
    p = FAST.with_dict({"effects.backlash_m": 50e-6})     # off: eq. 5.29, both kept
    assert effects_at(p, 0.0, 0.0)[:2] == (1500.0, 50e-6)


@pytest.mark.parametrize("href", [0.0, 1500.0])
def test_the_clearance_eats_the_interference_then_opens_lost_motion(href):
    kstar, m, z, g = contact_geometry(FAST)
    if href:
        inter = 6.0 * href / (z * (kstar + m * href) * g * g)     # 2 d0, Hertz
    else:
        inter = interference_from_preload(1500.0, kstar, m, z, g)  # eq. 5.21
    b0 = inter * g                         # the interference along the contact normal
    assert worn_nut(1500.0, 0.0, kstar, m, z, g, href) == (1500.0, 0.0)
    left = [worn_nut(1500.0, f * b0, kstar, m, z, g, href) for f in (0.25, 0.5, 0.999)]
    assert [b for _, b in left] == [0.0] * 3
    assert 1500.0 > left[0][0] > left[1][0] > left[2][0] > 0.0
    assert left[2][0] < 5.0                                # continuous at the interference
    f, b = worn_nut(1500.0, b0 + 30e-6, kstar, m, z, g, href)
    assert f == 0.0 and b == pytest.approx(30e-6, rel=1e-9)
    if href:
        assert left[1][0] == pytest.approx(1500.0 * 0.5 ** 1.5, rel=1e-12)
    assert worn_nut(0.0, 40e-6, kstar, m, z, g, href) == (0.0, 40e-6)   # no preload
    for c in (0.3 * b0, 2.0 * b0):                         # compiled = Python
        assert K._worn_nut(1500.0, c, kstar, m, z, g, href) == pytest.approx(
            worn_nut(1500.0, c, kstar, m, z, g, href), rel=1e-14)


def _deflection_range(params: PlantParams, n: int = 80) -> float:
    plant = Plant(params)
    d = []
    for k in range(n):
        plant.step(3.0 * math.sin(k / 10.0))
        d.append(0.5 * (plant.x[K.X1] + plant.x[K.X2])
                 - plant.x[K.TH] * params.screw.lead_m / (2 * math.pi))
    return float(np.ptp(d))


def test_backlash_under_a_preload_is_lost_motion_only_with_the_interference():
    # eq. 5.29's preload force (+-1.5 kN per half) takes up 50 um of backlash under a
    # +-2 kN load (1 kN per half): the nut moves as without backlash
    stiff = _deflection_range(FAST)
    off = _deflection_range(FAST.with_dict({"effects.backlash_m": 50e-6}))
    assert off == pytest.approx(stiff, rel=0.05)
    # the clearance first eats the interference (~6 um along the normal), then the load's
    # reversals cross the rest: tens of um of lost motion
    on = FAST.with_dict({"effects.backlash_m": 50e-6, "screw.preload_by_interference": True})
    assert effects_at(on, 0.0, 0.0)[0] == 0.0
    plant = Plant(on)
    plant.step(0.0)
    assert plant.out[K.O_PRELOAD] == 0.0 and 40e-6 < plant.out[K.O_BACKLASH] < 50e-6
    assert _deflection_range(on) > 20e-6 > 5.0 * stiff
