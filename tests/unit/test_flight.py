"""The seeded flight profile and the aero load: determinism, phase content,
parameter checks, the aero load's sign and gain, and the gusts."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from bench import BenchError
from bench.profiles.catalog import make_profile
from bench.profiles.flight import GRID_S
from bench.sim.control import Controller, ControllerParams
from bench.sim.harness import simulate
from plant_rt.aero import gust_sequence
from plant_rt.model import Plant
from plant_rt.params import PlantParams

FAST = {"drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic"}


def grid(prof):
    return np.arange(int(round(prof.duration_s / GRID_S))) * GRID_S


def test_flight_is_seeded():
    a, b = make_profile("flight", seed=3), make_profile("flight", seed=3)
    c = make_profile("flight", seed=4)
    t = grid(a)
    assert np.array_equal(a.position(t), b.position(t))
    assert not np.array_equal(a.position(t), c.position(t))
    assert a.phases == c.phases


def test_flight_phases_and_their_content():
    prof = make_profile("flight", duration_s=60.0, severity=1.0, turbulence_m=0.3e-3)
    t = grid(prof)
    x = prof.position(t)
    names = [p[0] for p in prof.phases]
    assert names == ["ground-test", "take-off", "cruise", "manoeuvres", "landing"]
    assert prof.phases[0][1] == 0.0 and prof.phases[-1][2] == pytest.approx(60.0)
    assert all(p[2] == q[1] for p, q in zip(prof.phases, prof.phases[1:], strict=False))
    # the ground test is the thesis' HUMS maneuver: the sine profile, +-0.5 mm, 2 Hz
    g0, g1 = prof.phase("ground-test")
    m = t < g1
    np.testing.assert_allclose(x[m], make_profile("sine").position(t[m]), atol=1e-15)
    # take-off: the rotation reaches 8 mm
    m = (t >= prof.phase("take-off")[0]) & (t < prof.phase("take-off")[1])
    assert np.max(x[m]) == pytest.approx(8e-3, abs=0.5e-3)
    # cruise: small, fast motions about the 2 mm trim, coloured (below ~5 Hz)
    c0, c1 = prof.phase("cruise")
    m = (t >= c0 + 2.0) & (t < c1 - 0.5)
    dev = x[m] - 2e-3
    assert 0.2e-3 < np.std(dev) < 0.4e-3 and abs(np.mean(dev)) < 0.2e-3
    f, pxx = signal.welch(dev, fs=1 / GRID_S, nperseg=4096)
    assert np.sum(pxx[f > 6.0]) < 0.05 * np.sum(pxx)
    assert np.sum(pxx[(f > 0.5) & (f < 6.0)]) > 0.5 * np.sum(pxx)
    # manoeuvres: doublets of up to 8 mm both ways about the trim
    m0, m1 = prof.phase("manoeuvres")
    m = (t >= m0) & (t < m1)
    assert np.max(np.abs(x[m] - 2e-3)) > 2.4e-3
    assert np.max(x[m]) > 2e-3 + 1e-3 and np.min(x[m]) < 2e-3 - 1e-3
    # landing: the flare, then neutral on the ground
    l0, l1 = prof.phase("landing")
    m = (t >= l0) & (t < l1)
    assert np.max(x[m]) == pytest.approx(6e-3, abs=1e-3)
    assert abs(x[-1]) < 1e-9
    # moves no faster than the nut's 50 mm/s (eq. 5.33) at severity 1
    assert np.max(np.abs(np.diff(x))) / GRID_S < 0.05


def test_a_short_flight_is_the_start_of_a_30_s_one():
    short, full = make_profile("flight", duration_s=2.0), make_profile("flight", duration_s=30.0)
    assert short.duration_s == 2.0 and short.phases == (("ground-test", 0.0, 2.0),)
    t = np.arange(0.0, 2.0, GRID_S)
    assert np.array_equal(short.position(t), full.position(t))
    mid = make_profile("flight", duration_s=12.0)
    assert [p[0] for p in mid.phases] == ["ground-test", "take-off", "cruise"]
    assert mid.phases[-1][2] == 12.0


def test_severity_scales_the_moves():
    t = np.arange(0.0, 60.0, GRID_S)
    x1 = make_profile("flight", severity=1.0).position(t)
    x2 = make_profile("flight", severity=2.0).position(t)
    assert np.max(x2) == pytest.approx(2 * np.max(x1), rel=0.1)


@pytest.mark.parametrize("kw, match", [
    ({"severity": 0.0}, "severity"), ({"severity": 4.0}, "severity"),
    ({"duration_s": 0.0}, "duration_s"), ({"seed": 1.5}, "seed"), ({"seed": -1.0}, "seed"),
    ({"turbulence_m": -1e-3}, "turbulence_m"), ({"turbulence_m": math.nan}, "turbulence_m"),
])
def test_flight_parameters_are_checked(kw, match):
    with pytest.raises(BenchError, match=match):
        make_profile("flight", **kw)


@pytest.mark.parametrize("target", [10e-3, -6e-3])
def test_aero_load_sign_and_gain(target):
    """No gusts: F_ext = K_aero x_n, restoring (opposes positive motion, eq. 5.30)."""
    gain = 3e5
    p = PlantParams().with_dict({**FAST, "load.kind": "aero", "load.gust_std_n": 0.0,
                                 "load.aero_gain_n_per_m": gain})
    tr = simulate(make_profile("step", amplitude_m=target, duration_s=1.0), p)
    x_end, f_end = tr["true_position_m"][-1], tr["ext_force_n"][-1]
    assert x_end == pytest.approx(target, rel=0.02)
    assert np.sign(f_end) == np.sign(target)
    assert f_end == pytest.approx(gain * x_end, rel=1e-3)
    # the load cell reads it, one period later, within its 2 N noise-free resolution
    assert tr["load_force_n"][-1] == pytest.approx(tr["ext_force_n"][-2], abs=1e-9)


def test_gusts_are_seeded_coloured_and_the_same_live_and_in_process():
    p = PlantParams().with_dict({"load.kind": "aero", "load.gust_std_n": 1000.0,
                                 "load.gust_time_constant_s": 0.1})
    g = gust_sequence(p, 20000)
    assert np.array_equal(g, gust_sequence(p, 20000))
    assert not np.array_equal(g, gust_sequence(p.with_dict({"load.gust_seed": 8}), 20000))
    assert np.std(g) == pytest.approx(1000.0, rel=0.15)
    lag = int(0.1 / 1e-3)                    # correlation e^-1 at one time constant
    r = np.corrcoef(g[:-lag], g[lag:])[0, 1]
    assert r == pytest.approx(math.exp(-1.0), abs=0.1)
    plant = Plant(p)
    live = []
    for _ in range(50):
        live.append(plant.inputs(0.0)[9])      # U_GUST
        plant.step(0.0)
    assert np.array_equal(np.array(live), g[:50])
    assert np.all(gust_sequence(PlantParams(), 10) == 0.0)


def test_compiled_flight_equals_plant_step_with_aero_and_wear():
    """The in-process loop and the live node's Plant.step agree under the aero load (gusts)
    and Archard wear (effects fed back each period)."""
    p = PlantParams().with_dict({**FAST, "load.kind": "aero", "wear.kind": "archard",
                                 "wear.acceleration": 1e6, "effects.preload_n": 2000.0})
    prof = make_profile("flight", duration_s=30.0)
    n = 3000
    tr = simulate(prof, p, duration_s=n * 1e-3, chunk_s=0.7)
    plant, ctrl = Plant(p), Controller(ControllerParams())
    applied, pos, cur = 0.0, [], []
    for k in range(n):
        m = plant.measure()
        sp, spd = prof.setpoint(k * 1e-3)
        d = ctrl.step(sp, spd, prof.mode, m.position_m, m.motor_speed_rad_s)
        pos.append(m.position_m)
        cur.append(m.current_a)
        plant.step(applied)
        applied = d
    np.testing.assert_allclose(tr["position_m"], pos, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(tr["current_a"], cur, rtol=1e-9, atol=1e-12)
    assert tr["preload_n"][-1] < 2000.0
    assert plant.truth()["wear_volume_m3"] == pytest.approx(tr.meta["wear_volume_m3"],
                                                             rel=1e-12, abs=0.0)
