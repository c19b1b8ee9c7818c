"""The independent actuator's physics (indie_plant): each law checked on its own,
through the pure-Python versions of the compiled functions (no compilation here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from indie_plant import physics as ph
from indie_plant.params import IDX, IndieParams

contact_force = ph.contact_force.py_func
preload_deflection = ph.preload_deflection.py_func
stribeck = ph.stribeck.py_func
lugre_update = ph.lugre_update.py_func
quantise = ph.quantise.py_func


def _motor_torque(i: float, th: float, p: np.ndarray) -> float:
    return ph.motor_torque.py_func(i, th, p)


def test_hertz_contact_force_grows_with_deflection_to_the_power_1_5():
    kh = IndieParams().hertz_n_per_m15
    d = np.geomspace(1e-7, 2e-5, 12)
    f = np.array([contact_force(x, 0.0, kh, 4.0) for x in d])
    slope = np.polyfit(np.log(d), np.log(f), 1)[0]
    assert slope == pytest.approx(1.5, abs=1e-9)
    assert contact_force(-1e-6, 0.0, kh, 4.0) == 0.0          # a half off its balls
    assert contact_force(1e-6, -1e6, kh, 4.0) == 0.0          # never pulls


def test_preload_seats_each_half_on_its_deflection_and_backlash_opens_a_dead_zone():
    p = IndieParams()
    d0 = preload_deflection(p.preload_n, p.hertz_n_per_m15)
    assert contact_force(d0, 0.0, p.hertz_n_per_m15, 0.0) == pytest.approx(p.preload_n)
    assert 3e-6 < d0 < 1e-5                                   # a few um: Hertz
    # preload lost, 40 um of clearance: no force inside +-20 um, force beyond
    kh, half = p.hertz_n_per_m15, 20e-6
    for delta in (-19e-6, 0.0, 19e-6):
        assert contact_force(delta - half, 0.0, kh, 0.0) == 0.0
        assert contact_force(-delta - half, 0.0, kh, 0.0) == 0.0
    assert contact_force(25e-6 - half, 0.0, kh, 0.0) > 0.0


@pytest.mark.parametrize("w", [-50.0, -3.0, -0.5, 0.2, 1.0, 4.0, 80.0])
def test_lugre_steady_state_is_the_stribeck_curve(w):
    """At constant speed the bristle settles where sigma0 z = g(w) sign(w): the friction
    torque is the Stribeck curve plus the viscous term (eq. I9-I10)."""
    p = IndieParams()
    g = stribeck(w, p.coulomb_nm, p.static_ratio, p.stribeck_rad_s)
    z = 0.0
    for _ in range(20000):
        z = lugre_update(z, w, g, p.bristle_nm_per_rad, 1e-5)
    torque = p.bristle_nm_per_rad * z + p.viscous_nm_s_per_rad * w     # dz/dt = 0
    want = math.copysign(g, w) + p.viscous_nm_s_per_rad * w
    assert torque == pytest.approx(want, rel=1e-6)
    assert stribeck(0.0, 1.0, 1.4, 2.0) == pytest.approx(1.4)          # static
    assert stribeck(100.0, 1.0, 1.4, 2.0) == pytest.approx(1.0)        # Coulomb


def test_cogging_repeats_per_slot_pitch_and_ripple_per_sixth_electrical_period():
    p = IndieParams().vector()
    cog = 2 * math.pi / IndieParams().cogging_per_rev
    th = np.linspace(0.0, 1.0, 37)
    t0 = np.array([_motor_torque(0.0, x, p) for x in th])
    assert np.allclose(t0, [_motor_torque(0.0, x + cog, p) for x in th], atol=1e-12)
    assert not np.allclose(t0, [_motor_torque(0.0, x + cog / 2, p) for x in th], atol=1e-6)
    q = p.copy()
    q[IDX["cogging_nm"]] = 0.0
    rip = 2 * math.pi / (6 * IndieParams().pole_pairs)
    t1 = np.array([_motor_torque(5.0, x, q) for x in th])
    assert np.allclose(t1, [_motor_torque(5.0, x + rip, q) for x in th], atol=1e-12)
    assert np.ptp(t1) == pytest.approx(2 * 0.02 * 0.9 * 5.0, rel=0.05)


def test_sensors_are_quantised_to_their_steps(monkeypatch):
    monkeypatch.setattr(ph, "quantise", quantise)       # pure Python: nothing compiled
    par = IndieParams()
    p = par.vector()
    rng = np.random.default_rng(3)
    istep = 80.0 / 4096
    lstep = 0.08 / 65536
    astep = 2 * math.pi / 16384
    x = ph.initial_state()
    hist = np.zeros((ph.HIST, 2))
    out = np.zeros(5)
    for k in range(30):
        x[ph.CUR], x[ph.TH], x[ph.LV1] = rng.normal(0, 5), rng.normal(0, 3), rng.normal(0, 1e-3)
        x[ph.LV2] = x[ph.LV1]
        ph.sense.py_func(x, p, hist, k, rng.standard_normal(3), out)
        for v, step in ((out[0], istep), (out[1], astep), (out[3], lstep)):
            assert abs(v / step - round(v / step)) < 1e-6
    assert quantise(100.0, istep, 40.0) == 40.0                     # full scale
    assert quantise(0.3 * istep, istep, 40.0) == 0.0


def test_parameters_are_checked_and_named():
    with pytest.raises(ValueError, match="outside"):
        IndieParams().with_dict({"lead_m": -1.0})
    with pytest.raises(ValueError, match="unknown"):
        IndieParams().with_dict({"no_such": 1.0})
    assert IndieParams().with_assignments(["backlash_m=5e-5"]).backlash_m == 5e-5


def test_only_draws_every_case_as_that_effect_and_leaves_the_default_draw_alone():
    from bench.gap import indiebench as IB
    cases = IB.make_cases(6, 2031, only="preload")
    assert [c.kind for c in cases] == ["single"] * 6
    assert all([t.name for t in c.truths] == ["preload"] for c in cases)
    assert len({tuple(sorted(c.truths[0].plant.items())) for c in cases}) == 6
    # the default draw: 30 % nominal, and fixed by the seed (the pool with lvdt_delay)
    default = IB.make_cases(20, 2025)
    assert sum(c.kind == "nominal" for c in default) == 6
    assert [t.name for t in default[0].truths] == ["lvdt_lag"]
    assert default[0].noise_seed == 329502222
    import pytest
    with pytest.raises(ValueError, match="unknown effect"):
        IB.make_cases(2, 1, only="cogging")


def test_gap_bench_only_is_refused_for_the_bench_generator_and_unknown_effects(capsys):
    from bench.cli import main
    assert main(["gap-bench", "--only", "preload", "--cases", "1"]) == 2
    assert "--only is for --generator independent" in capsys.readouterr().err
    assert main(["gap-bench", "--generator", "independent", "--only", "cogging",
                 "--cases", "1"]) == 2
    assert "unknown effect 'cogging'" in capsys.readouterr().err


def test_lvdt_delay_delays_the_lvdt_alone():
    """`lvdt_delay_periods`: the LVDT read that many SYNC periods late, on top of the
    common sensor delay; the encoder is not."""
    from indie_plant import physics as ph
    p = IndieParams().with_dict({"noise": 0.0, "lvdt_delay_periods": 3.0}).vector()
    x = ph.initial_state()
    hist = ph.initial_history(x, p)
    out = np.zeros(5)
    seen = []
    for k in range(8):
        x[ph.XN] = x[ph.LV1] = x[ph.LV2] = 1e-3 * k     # the nut (and the LVDT) moving
        x[ph.TH] = 0.01 * k
        ph.sense(x, p, hist, k, np.zeros(3), out)
        seen.append(out.copy())
    lv = [s[3] for s in seen]
    assert lv[5] == pytest.approx(2e-3, abs=2e-6)        # the sample of SYNC 2
    assert lv[7] == pytest.approx(4e-3, abs=2e-6)
    assert seen[5][1] > seen[4][1]                       # the encoder: today's angle
