"""Archard wear (plant_rt.wear): the laws, the mapping to preload, backlash and
friction, the kernel's accumulation against a hand calculation, and continuation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate
from plant_rt import kernel as K
from plant_rt import wear
from plant_rt.contacts import axial_stiffness, contact_geometry
from plant_rt.model import Plant, effects_at
from plant_rt.params import PlantParams

FAST = {"drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic"}
ARCHARD = {"wear.kind": "archard", "wear.coefficient_log_std": 0.0}


def test_wear_rate_is_archard():
    # V' = k F v / H: 1e-8 x 1 kN x 0.1 m/s / 7.4 GPa
    assert wear.wear_rate(1e-8, 1000.0, -0.1, 7.4e9) == pytest.approx(1.3513513513513513e-16, rel=1e-12,
                                                                      abs=0.0)


def test_coefficient_is_seeded_log_normal_and_hidden_in_the_plant():
    p = PlantParams()
    ks = np.array([wear.draw_coefficient(1e-8, 0.5, s) for s in range(400)])
    assert wear.draw_coefficient(1e-8, 0.5, 3) == wear.draw_coefficient(1e-8, 0.5, 3)
    assert np.median(ks) == pytest.approx(1e-8, rel=0.15, abs=0.0)
    assert np.std(np.log(ks)) == pytest.approx(0.5, rel=0.15)
    assert wear.draw_coefficient(1e-8, 0.0, 5) == 1e-8
    # off by default: the kernel accumulates nothing
    assert wear.kernel_wear_gain(p) == 0.0
    assert wear.coefficient(p.with_dict({"wear.acceleration": 10.0})) == pytest.approx(
        10 * wear.coefficient(p), abs=0.0)


@pytest.mark.parametrize("reading", ["contact", "axial"])
@pytest.mark.parametrize("preload", [0.0, 2000.0])
def test_wear_to_effects_is_monotonic(reading, preload):
    p = PlantParams().with_dict({"screw.stiffness_reading": reading,
                                 "effects.preload_n": preload})
    vols = np.concatenate([[0.0], np.geomspace(1e-13, 1e-7, 300)])
    eff = np.array([wear.wear_to_effects(v, p) for v in vols])
    assert tuple(eff[0]) == (0.0, 0.0, 1.0)
    assert np.all(np.diff(eff, axis=0) >= 0.0)          # loss, backlash, friction grow
    assert eff[-1, 0] == pytest.approx(preload)          # all preload gone in the end
    assert eff[-1, 1] > 100e-6 and eff[-1, 2] > 4.0
    if preload:
        # backlash opens only once the preload is gone
        opened = eff[:, 1] > 0
        assert np.all(eff[opened, 0] == pytest.approx(preload))
        assert not opened[:50].any()


def test_preload_interference_round_trip_and_backlash_inverse():
    p = PlantParams().with_dict({"effects.preload_n": 2000.0,
                                 "screw.stiffness_reading": "axial"})
    kstar, m, z, g = contact_geometry(p)
    d = wear.interference_from_preload(2000.0, kstar, m, z, g)
    assert d > 0 and wear.preload_from_interference(d, kstar, m, z, g) == pytest.approx(2000.0)
    v = wear.volume_for_backlash(100e-6, p)
    assert wear.wear_to_effects(v, p)[1] == pytest.approx(100e-6, rel=1e-9, abs=0.0)


def test_archard_constant_load_run_against_hand_calculation():
    """Constant screw speed against a constant 5 kN load: V = (k/H) sum|P| s with the
    contacts carrying load plus nut friction, 2 (F + F_s)/g over the 4 contacts of a
    ball pair times Z, and s = (r_m / 2 cos alpha) per radian."""
    f = 5000.0
    p = PlantParams().with_dict({**FAST, **ARCHARD, "load.kind": "step",
                                 "load.amplitude_n": f})
    tr = simulate(make_profile("velocity-step", speed_rad_s=100.0, stop_s=1.0,
                               duration_s=1.0), p)
    s = p.screw
    g = math.cos(math.radians(s.helix_angle_deg)) * math.sin(math.radians(s.contact_angle_deg))
    theta = tr["motor_angle_rad"][-1] * p.reducer.ratio           # screw radians
    k = wear.coefficient(p)
    hand = k / p.wear.hardness_pa * 2 * (f + s.nut_static_friction_n) / g \
        * 0.5 * s.nominal_radius_m / math.cos(math.radians(s.helix_angle_deg)) * theta
    assert theta > 20.0
    assert tr.meta["wear_volume_m3"] == pytest.approx(hand, rel=0.01, abs=0.0)   # 0.16 %


def test_wear_volume_alone_carries_the_wear_and_a_run_continues_from_it():
    """Half a run, then a new plant started from the worn volume (and the motion state),
    equals the whole run bit for bit: the volume is the only wear state."""
    p = PlantParams().with_dict({**FAST, **ARCHARD, "wear.acceleration": 3e5,
                                 "effects.preload_n": 2000.0})
    demand = 4.0 * np.sin(2 * math.pi * 3.0 * np.arange(600) * 1e-3)
    whole = Plant(p)
    for d in demand:
        whole.step(float(d))
    first = Plant(p)
    for d in demand[:300]:
        first.step(float(d))
    v1 = float(first.x[K.WEAR_V])
    assert v1 > 0
    second = Plant(p.with_dict({"wear.initial_volume_m3": v1}))
    assert second.x[K.WEAR_V] == v1
    second.x[:] = first.x
    for d in demand[300:]:
        second.step(float(d))
    assert np.array_equal(second.x, whole.x)
    assert whole.truth()["preload_n"] < 2000.0          # the wear showed during the run


def test_day_by_day_equals_one_long_run():
    """Two ground-test days, each from rest, the second from the first's worn volume, wear
    as much as one run of the two days with a rest between."""
    p = PlantParams().with_dict({**FAST, **ARCHARD, "wear.acceleration": 1e5,
                                 "effects.preload_n": 2000.0})
    day = make_profile("sine", cycles=4)
    d1 = simulate(day, p).meta["wear_volume_m3"]
    d2 = simulate(day, p.with_dict({"wear.initial_volume_m3": d1})).meta["wear_volume_m3"]
    # one run: day, 1 s of rest at 0, day again
    two = make_profile("sine", cycles=4)
    dur = two.duration_s

    def pos(t):
        return np.where(t < dur, two.position(t),
                        np.where(t < dur + 1.0, 0.0, two.position(t - dur - 1.0)))
    from bench.profiles.setpoints import Profile
    long = Profile("two-days", two.mode, 2 * dur + 1.0, pos, two.speed)
    one = simulate(long, p).meta["wear_volume_m3"]
    assert d2 > d1 > 0
    # 0.6 % apart (measured): the long run's second day starts where the first left the
    # nut and the ECU (stiction, the speed PI's integrator), the separate day from rest
    assert one == pytest.approx(d2, rel=0.01, abs=0.0)
    assert one != pytest.approx(d1, rel=0.3, abs=0.0)


def test_archard_effects_show_in_the_trace_and_truth():
    p = PlantParams().with_dict({**FAST, **ARCHARD, "wear.acceleration": 1e6,
                                 "effects.preload_n": 2000.0})
    tr = simulate(make_profile("sine", cycles=4), p)
    assert tr["preload_n"][0] == pytest.approx(2000.0)
    assert np.all(np.diff(tr["preload_n"]) <= 0) and tr["preload_n"][-1] < 2000.0
    assert np.all(np.diff(tr["friction_scale"]) >= 0) and tr["friction_scale"][-1] > 1.0
    v = tr.meta["wear_volume_m3"]
    assert effects_at(p, 0.0, v)[0] < tr["preload_n"][-1] + 1e-6


def test_axial_reading_gives_100_n_per_um():
    p = PlantParams()
    assert axial_stiffness(p) == pytest.approx(1.047e9, rel=1e-3)   # today's reading
    q = p.with_dict({"screw.stiffness_reading": "axial"})
    assert axial_stiffness(q) == pytest.approx(1e8)
    # a 3 kN preload: 1/(1 + m F_pr / k_c) of the deflection, 0.564
    assert axial_stiffness(q) / axial_stiffness(q, 3000.0) == pytest.approx(0.5640, abs=1e-3)

