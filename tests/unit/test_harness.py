"""The compiled in-process loop equals the plant's public one-SYNC step driven by the
ECU controller object, period by period (the live node uses Plant.step)."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.profiles.catalog import make_profile
from bench.sim.control import Controller, ControllerParams
from bench.sim.harness import simulate
from plant_rt.model import Plant
from plant_rt.params import PlantParams


def python_loop(profile, params):
    """Plant.step + Controller.step with the bus timing (demand applied one SYNC later)."""
    if profile.params_overrides:
        params = params.with_dict(profile.params_overrides)
    plant = Plant(params)
    ctrl = Controller(ControllerParams())
    n = int(round(profile.duration_s / params.sim.sync_period_s))
    rows = []
    applied = 0.0
    for k in range(n):
        t = k * params.sim.sync_period_s
        m = plant.measure()
        sp_pos, sp_spd = profile.setpoint(t)
        d = ctrl.step(sp_pos, sp_spd, profile.mode, m.position_m, m.motor_speed_rad_s)
        rows.append((m.current_a, m.motor_speed_rad_s, m.position_m, m.motor_angle_rad, d))
        plant.step(applied)
        applied = d
    return np.array(rows)


@pytest.mark.parametrize("name, extra", [
    ("sine", {}),
    ("velocity-step", {"effects.backlash_m": 50e-6}),
    ("sine", {"sensors.noise": True, "sensors.noise_seed": 7,
              "effects.sensor_delay_s": 0.002, "effects.friction_scale": 2.0}),
])
def test_compiled_loop_equals_plant_step(name, extra):
    params = PlantParams().with_dict({"drive.pwm_mode": "averaged",
                                      "sim.ball_model": "quasistatic", **extra})
    prof = make_profile(name, duration_s=0.3) if name == "sine" else make_profile(name)
    tr = simulate(prof, params, chunk_s=0.07)   # chunks must not change anything
    ref = python_loop(prof, params)
    assert len(tr) == len(ref)
    np.testing.assert_allclose(tr["current_a"], ref[:, 0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(tr["motor_speed_rad_s"], ref[:, 1], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(tr["position_m"], ref[:, 2], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(tr["motor_angle_rad"], ref[:, 3], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(tr["current_demand_a"], ref[:, 4], rtol=1e-9, atol=1e-12)


def test_noise_is_seeded_and_changes_with_seed():
    prof = make_profile("sine", duration_s=0.2)
    base = PlantParams().with_dict({"drive.pwm_mode": "averaged", "sensors.noise": True})
    a = simulate(prof, base)
    b = simulate(prof, base)
    c = simulate(prof, base.with_dict({"sensors.noise_seed": 2}))
    assert np.array_equal(a["current_a"], b["current_a"])
    assert not np.array_equal(a["current_a"], c["current_a"])


def test_profiles_reject_bad_input():
    with pytest.raises(BenchError, match="unknown profile"):
        make_profile("square")
    with pytest.raises(BenchError, match="has no parameter"):
        make_profile("sine", amplitude=1.0)
    with pytest.raises(BenchError, match="finite"):
        make_profile("sine", amplitude_m=float("nan"))
    with pytest.raises(BenchError, match="duration"):
        make_profile("step", duration_s=-1.0)
