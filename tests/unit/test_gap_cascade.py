"""The generic cascade for unknown controllers and the measured-current re-simulation
(`bench.gap.cascade`, `bench.gap.resim`)."""

import math

import numpy as np

from bench.gap import resim as R
from bench.gap.calibrate import initial_cascade
from bench.gap.cascade import Cascade, logged_inputs, replay, replay_one_step
from bench.profiles.maneuvers import excitation
from bench.signals.trace import Trace
from bench.sim.control import ControllerParams
from plant_rt.params import PlantParams

FAST = PlantParams().with_dict({**R.FAST, "sensors.noise": False})


def _drive(n: int = 800) -> R.Drive:
    prof = excitation(n * 1e-3, 0.0)
    t = np.arange(n) * 1e-3
    return R.Drive(t, prof.position(t), prof.speed(t), np.full(n, float(prof.mode)),
                   np.full(n, np.nan), 0.0, 0.0)


def test_cascade_like_the_ecu_is_the_ecu():
    """The generic law with the ECU's structure (P on the LVDT, every SYNC) and gains
    gives the ECU's re-simulation bit for bit."""
    cp = ControllerParams()
    c = Cascade("lvdt", cp.position_kp_rad_s_per_m, 0.0, cp.speed_kp_a_s_per_rad,
                cp.speed_ki_a_per_rad, cp.speed_limit_rad_s, cp.current_limit_a, 1)
    d = _drive()
    a = R.closed_loop(FAST, d)
    d.cascade = c
    b = R.closed_loop(FAST, d)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert np.ptp(a["position_m"]) > 1e-4


TRAVEL = R.angle_to_travel(FAST)
TRUE = Cascade("encoder", 2 * math.pi * 8 / TRAVEL, 2 * math.pi * 8 / TRAVEL * 2 * math.pi,
               0.4, 0.4 * 2 * math.pi * 3, 240.0, 25.0, 2)


def _synthetic(c: Cascade = TRUE, n: int = 2500) -> dict[str, np.ndarray]:
    """The plant's log under `c` (the law saw exactly these samples)."""
    d = _drive(n)
    d.cascade = c
    cols = R.closed_loop(FAST, d)
    cols.update({"setpoint_position_m": d.sp_pos, "setpoint_speed_rad_s": d.sp_spd,
                 "mode": d.mode})
    assert np.mean(np.abs(cols["current_demand_a"]) < 0.99 * c.current_limit_a) > 0.8
    return cols


def test_one_step_replay_is_the_law_at_the_true_gains():
    cols = _synthetic()
    ref, meas = logged_inputs(cols)
    d = replay(TRUE.vector(1e-3, TRAVEL), ref, meas)
    np.testing.assert_allclose(d, cols["current_demand_a"], atol=1e-9)
    d = replay_one_step(TRUE.vector(1e-3, TRAVEL), ref, meas, cols["current_demand_a"])
    np.testing.assert_allclose(d, cols["current_demand_a"], atol=1e-9)
    assert np.ptp(d) > 1.0
    wrong = Cascade("encoder", TRUE.kp_pos, TRUE.ki_pos, 0.3, TRUE.ki_spd, 240.0, 25.0, 2)
    d2 = replay_one_step(wrong.vector(1e-3, TRAVEL), ref, meas, cols["current_demand_a"])
    assert np.max(np.abs(d2 - d)) > 0.01


def test_fit_to_demand_finds_the_gains():
    from bench.gap.calibrate import fit_cascade_to_demand
    cols = _synthetic()
    tr = Trace({"t_s": np.arange(len(cols["mode"])) * 1e-3, **cols}, {})
    c0 = initial_cascade(FAST, tr, "encoder", 2)
    got, e_fit, e_ho = fit_cascade_to_demand(tr, c0, TRAVEL, 1800)
    assert e_fit < 1e-6 and e_ho < 0.5       # the speed limit is reached after 1.8 s only
    for k in ("kp_pos", "ki_pos", "kp_spd", "ki_spd"):
        assert math.isclose(getattr(got, k), getattr(TRUE, k), rel_tol=1e-4), k
    assert Cascade.from_dict(got.describe()) == got


def test_measured_current_follows_the_log():
    """The plant's own noise-free log re-simulated from its current: the current tracks
    (the tracking passes), the mechanics stay near the log between re-starts."""
    d = _drive(1500)
    log = R.closed_loop(FAST, d)
    d.resim = "measured-current"
    d.current_meas = log["current_a"]
    d.angle_meas = log["motor_angle_rad"]
    out = R.closed_loop(FAST, d)
    assert np.sqrt(np.mean((out["current_a"] - log["current_a"]) ** 2)) < 0.02 * np.ptp(
        log["current_a"])
    err = np.sqrt(np.mean((out["motor_speed_rad_s"] - log["motor_speed_rad_s"]) ** 2))
    assert err < 0.05 * np.ptp(log["motor_speed_rad_s"])


def test_a_log_naming_its_controller_is_re_simulated_under_it():
    from bench.gap.problem import drive_of
    n = 300
    cols = {"t_s": np.arange(n) * 1e-3, "mode": np.ones(n), "position_m": np.zeros(n),
            "motor_angle_rad": np.zeros(n), "current_a": np.zeros(n),
            "setpoint_position_m": np.zeros(n)}
    assert drive_of(Trace(cols, {}), params=FAST).cascade is None
    d = drive_of(Trace(cols, {"controller": {"method": "fitted-cascade",
                                             "cascade": TRUE.describe()}}), params=FAST)
    assert d.cascade == TRUE and d.resim == "closed-loop"
    d = drive_of(Trace(cols, {"controller": {"method": "measured-current"}}), params=FAST)
    assert d.resim == "measured-current" and d.current_meas is not None
