"""The gap diagnosis' re-simulation reproduces the bench's closed loop exactly, and its
path replays and kinematic paths leave no residual on a nominal run."""

from __future__ import annotations

import numpy as np
import pytest

from bench.gap import problem as P
from bench.gap import resim as R
from bench.profiles.maneuvers import excitation
from bench.sim.harness import simulate
from plant_rt.params import PlantParams

FAST = PlantParams().with_dict(R.FAST)


def drive_of(tr):
    return P.drive_of(tr.measured(), "absolute", FAST)


@pytest.mark.parametrize("extra", [
    {},
    {"effects.backlash_m": 40e-6, "effects.sensor_delay_s": 0.002},
    {"sensors.lvdt_gain": 1.05, "sensors.lvdt_offset_m": 1e-4, "sensors.current_offset_a": 0.2},
])
def test_closed_loop_equals_harness(extra):
    params = FAST.with_dict(extra)
    tr = simulate(excitation(1.5, load_n=0.0), params)
    cols = R.closed_loop(params, drive_of(tr))
    for c in ("current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m",
              "current_demand_a"):
        np.testing.assert_array_equal(cols[c], tr[c], err_msg=c)


def test_closed_loop_replays_the_logged_load():
    """An axial force held over each period is replayed from the load cell (the
    cell at SYNC k reads period k - 1); the maneuver's continuous sine load, held per
    period in the re-simulation, stays far below the sensors' noise."""
    def force(t):
        return 1800.0 * np.sin(2 * np.pi * 0.9 * t) + 400.0 * (t > 0.7)

    tr = simulate(excitation(1.5, load_n=0.0), FAST, ext_force_n=force)
    assert np.max(np.abs(tr["load_force_n"][1:] - force(tr.t)[:-1])) < 1e-9
    cols = R.closed_loop(FAST, drive_of(tr))
    for c in ("current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m"):
        # the cell's period average of a held force differs from it in the last bit only
        np.testing.assert_allclose(cols[c], tr[c], rtol=1e-9, atol=1e-12, err_msg=c)
    unloaded = simulate(excitation(1.5, load_n=0.0), FAST)
    assert np.max(np.abs(unloaded["current_a"] - tr["current_a"])) > 0.05   # the load acts
    tl = simulate(excitation(1.5), FAST)          # 2 kN sine load from the plant's params
    cols = R.closed_loop(FAST, drive_of(tl))
    assert np.max(np.abs(cols["position_m"] - tl["position_m"])) < 0.2e-6
    assert np.max(np.abs(cols["current_a"] - tl["current_a"])) < 0.02


def test_open_loop_replay_of_the_logged_demand_is_exact():
    tr = simulate(excitation(1.0, load_n=0.0), FAST)
    cols = R.open_loop(FAST, drive_of(tr))
    np.testing.assert_array_equal(cols["current_a"], tr["current_a"])
    np.testing.assert_array_equal(cols["position_m"], tr["position_m"])


def test_screw_path_is_quiet_without_backlash_and_shows_lost_motion_with_it():
    tr = simulate(excitation(2.0, load_n=0.0), FAST)
    kin = R.second_order(tr["motor_angle_rad"] * R.angle_to_travel(FAST), 1e-3,
                         FAST.sensors.lvdt_natural_rad_s, FAST.sensors.lvdt_damping)
    assert np.sqrt(np.mean((tr["position_m"] - kin) ** 2)) < 0.5e-6
    tb = simulate(excitation(2.0, load_n=0.0), FAST.with_dict({"effects.backlash_m": 50e-6}))
    kin = R.second_order(tb["motor_angle_rad"] * R.angle_to_travel(FAST), 1e-3,
                         FAST.sensors.lvdt_natural_rad_s, FAST.sensors.lvdt_damping)
    lost = np.max(tb["position_m"] - kin) - np.min(tb["position_m"] - kin)
    assert 40e-6 < lost < 90e-6      # the backlash plus transients at current-limited steps


def test_initial_position_from_the_absolute_encoder():
    """A log that starts with the nut away from zero re-simulates from there at rest."""
    params = FAST
    tr = simulate(excitation(0.4), params)
    d = drive_of(tr)
    d.x0_true_m = 2e-3
    d.sp_pos = d.sp_pos + 2e-3
    cols = R.closed_loop(params, d)
    assert abs(cols["position_m"][0] - 2e-3) < 1e-9
    assert abs(cols["motor_angle_rad"][0] * R.angle_to_travel(params) - 2e-3) < 1e-6


def test_a_logged_load_step_marks_the_load_change_regime():
    from bench.gap import localise as L
    from bench.profiles.catalog import make_profile
    params = FAST.with_dict({"sensors.noise": True, "load.kind": "step",
                             "load.amplitude_n": 1500.0, "load.start_s": 1.0})
    tr = simulate(make_profile("sine", duration_s=2.0), params).measured()
    reg = L.regimes(P.build(tr, PlantParams()))
    idx = np.flatnonzero(reg == L.REGIMES.index("load_change"))
    # the 10 ms step at 1.0 s, widened by the 10 ms rate window and 50 ms either side
    assert len(idx) > 50 and 930 <= idx.min() <= 1000 and 1000 <= idx.max() <= 1090
