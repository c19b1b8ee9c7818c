"""The monitoring model (eq. 6.1-6.2) and its Nelder-Mead position gain (row H1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import BenchError
from bench.hums import monitor as M
from bench.profiles.catalog import make_profile
from bench.signals.trace import Trace
from bench.sim.control import ControllerParams, position_gain_for_bandwidth
from bench.sim.harness import simulate
from plant_rt.params import PlantParams

FAST = {"drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic"}


def test_fitted_gain_reproduces_the_nominal_trace():
    fit, real = M.fitted()
    nom = M.nominal_for(real.measured(), fit.gain_rad_s_per_m)
    # superimposed: position within 0.1 % RMS of the signal, current within 8 %
    assert fit.converged and fit.relative_residual < 1e-3
    assert fit.rms_start_m > 100 * fit.rms_residual_m       # the start gain 20 was far off
    di = real["current_a"] - nom["current_a"]
    assert np.sqrt(np.mean(di ** 2)) < 0.08 * np.sqrt(np.mean(real["current_a"] ** 2))
    # the fit lands on the plant ECU's own gain (both in SI and thesis units)
    assert fit.gain_rad_s_per_m == pytest.approx(fit.plant_gain_rad_s_per_m, rel=0.01)
    assert fit.gain_thesis_units == pytest.approx(fit.gain_rad_s_per_m / 285.7)


def test_fit_tracks_the_plant_gain_not_the_thesis_number():
    """With the plant's ECU designed for 3 Hz instead of 6 Hz, the fit must find that
    gain (about 332 thesis units), not 663: the fit is informative, not a constant."""
    cp = ControllerParams(position_kp_rad_s_per_m=position_gain_for_bandwidth(3.0))
    params = PlantParams().with_dict(FAST)
    real = simulate(make_profile("sine"), params, cp).measured()
    fit = M.fit_gain(real, M.MonitorParams.from_plant(params), cp)
    assert fit.gain_rad_s_per_m == pytest.approx(cp.position_kp_rad_s_per_m, rel=0.02)
    assert abs(fit.gain_thesis_units - M.THESIS_FITTED_GAIN) > 250


def test_open_loop_cruise_current_is_the_doubled_friction_of_eq_6_1():
    """At a constant 30 rad/s motor speed the monitor's current must hold
    2 C_f(omega) tau / (eta k_t) (eq. 6.1 at zero acceleration)."""
    mp = M.MonitorParams.from_plant()
    prof = make_profile("velocity-step", stop_s=0.6, duration_s=0.6)
    tr = M.simulate_monitor(prof, mparams=mp)
    w_screw = 30.0 * mp.ratio
    cf = mp.static_friction_nm * (1 + mp.stribeck_amplitude * math.exp(
        -w_screw / mp.stribeck_velocity_rad_s)) + mp.viscous_friction_nm_s * w_screw / mp.ratio
    expect = 2 * cf * mp.ratio / (mp.efficiency * mp.kt_nm_per_a)
    cruise = tr["current_a"][(tr.t > 0.4) & (tr.t < 0.6)]
    assert np.mean(cruise) == pytest.approx(expect, rel=0.01)
    assert np.mean(tr["motor_speed_rad_s"][(tr.t > 0.4)]) == pytest.approx(30.0, abs=0.05)
    # eq. 6.2: nut position = p / 2 pi x screw angle
    x = tr["true_position_m"]
    ang = tr["motor_angle_rad"]
    assert x[-1] == pytest.approx(ang[-1] * mp.ratio * mp.lead_m / (2 * math.pi), rel=1e-3)


def test_monitor_stays_stuck_below_breakaway():
    mp = M.MonitorParams.from_plant()
    mon = M.Monitor(mp, 1e5)
    breakaway_a = 2 * mp.static_friction_nm * (1 + mp.stribeck_amplitude) * mp.ratio / (
        mp.efficiency * mp.kt_nm_per_a)
    n = 300
    # speed mode with a tiny speed set-point: the PI winds up slowly; stays below breakaway
    out = mon.run(np.zeros(n), np.full(n, 1e-4), np.full(n, 2.0))
    assert np.all(np.abs(out[:, 0]) < breakaway_a)
    assert np.all(out[:, 5] == 0.0)


def test_gap_interface_and_chunking_are_consistent():
    from bench.gap.resim import Drive

    prof = make_profile("sine")
    whole = M.simulate_monitor(prof, 1.8e5)
    t = whole.t
    d = Drive(t, whole["setpoint_position_m"], whole["setpoint_speed_rad_s"], whole["mode"],
              demand=np.full(len(t), np.nan), x0_m=0.0)
    cols = M.closed_loop(PlantParams(), d, position_kp_rad_s_per_m=1.8e5)
    np.testing.assert_allclose(cols["current_a"], whole["current_a"], rtol=0, atol=0)
    mon = M.Monitor(M.MonitorParams.from_plant(), 1.8e5)
    parts = [mon.run(d.sp_pos[a:a + 333], d.sp_spd[a:a + 333], d.mode[a:a + 333])
             for a in range(0, len(t), 333)]
    np.testing.assert_array_equal(np.concatenate(parts)[:, 0], whole["current_a"])


def test_nominal_for_needs_the_set_points_and_the_sync_rate():
    tr = Trace({"t_s": np.arange(10) * 1e-3, "position_m": np.zeros(10)})
    with pytest.raises(BenchError, match="setpoint_position_m"):
        M.nominal_for(tr)
    slow = Trace({"t_s": np.arange(10) * 1e-2, "setpoint_position_m": np.zeros(10),
                  "setpoint_speed_rad_s": np.zeros(10), "mode": np.ones(10)})
    with pytest.raises(BenchError, match="SYNC period"):
        M.nominal_for(slow)
    with pytest.raises(BenchError, match="substep"):
        M.MonitorParams.from_plant(substep_s=1.0)


def test_monitor_follows_a_drive_whose_current_pi_follows_its_winding():
    """The monitor's current PI is the drive's: with drive.current_pi_follows_winding the
    integral gain is kp R / L of the winding, as plant_rt.model builds it."""
    from plant_rt import kernel as K
    from plant_rt.model import param_vector
    from plant_rt.params import PlantParams
    p = PlantParams().with_dict({"drive.current_pi_follows_winding": True,
                                 "motor.resistance_ohm": 1.2})
    mp = M.MonitorParams.from_plant(p)
    assert mp.current_ki_v_per_as == pytest.approx(param_vector(p)[K.P_KII], rel=1e-12)
    assert mp.current_ki_v_per_as != pytest.approx(PlantParams().drive.current_ki_v_per_as)
    plain = M.MonitorParams.from_plant(PlantParams())
    assert plain.current_ki_v_per_as == PlantParams().drive.current_ki_v_per_as
