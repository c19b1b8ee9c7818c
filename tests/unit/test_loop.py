"""The one closed loop (`bench.sim.loop`): a controller plugs in without another loop, the
loop's stop on a non-finite state, and the laws and constants it shares (the clamped PI,
I_eq and C_s) are one copy each."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from bench.gap import problem as P
from bench.gap import resim as R
from bench.hums import monitor as M
from bench.profiles.catalog import make_profile
from bench.sim.control import C_LAST, NC, NK, ControllerParams, controller_step
from bench.sim.harness import run_inputs, simulate
from bench.sim.loop import (
    NT,
    ecu_reference,
    kernel_advance,
    kernel_measure,
    kernel_truth,
    no_columns,
    no_prepare,
    run_chunks,
    run_loop,
)
from plant_rt import kernel as K
from plant_rt.model import (
    Plant,
    equivalent_inertia,
    param_vector,
    sensor_vector,
    static_friction,
    viscous_friction,
)
from plant_rt.params import PlantParams
from plant_rt.pi import clamped_pi

FAST = PlantParams().with_dict(R.FAST)


# --- a third controller: a cascade sampled every `hold` SYNC periods (a foreign rig) ------

@njit(cache=True)
def held_cascade(c, kvec, ref, kk, meas, kd):  # pragma: no cover - compiled
    """The ECU law with its own gains, limits and sample time, computed every kvec[NK]
    SYNC periods and held in between (state c[NC]: periods left until the next sample)."""
    if c[NC] <= 0.0:
        c[NC] = kvec[NK]
        controller_step(c[:NC], kvec[:NK], ref[kk, 0], ref[kk, 1], ref[kk, 2],
                        meas[kd, K.M_POS], meas[kd, K.M_SPEED])
    c[NC] -= 1.0
    return c[C_LAST]


@njit(cache=True)
def held_cascade_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out,
                          dem_out, diag_out, truth_out, applied, k0):  # pragma: no cover
    return run_loop(no_prepare, kernel_measure, kernel_truth, kernel_advance, held_cascade,
                    x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                    diag_out, truth_out, applied, k0)


def run_held(profile, params, cparams, hold, chunk=None):
    ri = run_inputs(profile, params)
    n = len(ri.t)
    plant = Plant(params)
    meas, dem = np.zeros((n, K.NM)), np.zeros(n)
    kvec = np.append(cparams.vector(), float(hold))
    got = run_chunks(held_cascade_on_plant, plant.x, plant.param_vector, plant.sensor_vector,
                     no_columns(n), ri.u, ri.noise,
                     ecu_reference(ri.sp_pos, ri.sp_spd, ri.mode), kvec, np.zeros(NC + 1),
                     0, meas, dem, np.zeros((n, K.NO)), np.zeros((n, NT)), chunk=chunk)
    assert got == n
    return meas, dem


def test_a_held_cascade_plugs_into_the_same_loop():
    prof = make_profile("sine", duration_s=0.6)
    params = FAST.with_dict({"sensors.noise": True})
    # sampled every SYNC with the ECU's gains it is the ECU, bit for bit, chunked or not
    ecu = simulate(prof, params)
    meas, dem = run_held(prof, params, ControllerParams(), 1, chunk=77)
    np.testing.assert_array_equal(dem, ecu["current_demand_a"])
    np.testing.assert_array_equal(meas[:, K.M_POS], ecu["position_m"])
    # a foreign rig's cascade: softer gains, 10 A limit, sampled every 3 ms
    cp = ControllerParams(position_kp_rad_s_per_m=0.5 * ControllerParams().
                          position_kp_rad_s_per_m, speed_kp_a_s_per_rad=0.25,
                          speed_ki_a_per_rad=4.0, current_limit_a=10.0,
                          sample_period_s=3e-3)
    meas, dem = run_held(prof, params, cp, 3)
    assert np.all(dem[0::3] == dem[1::3]) and np.all(dem[0::3] == dem[2::3])
    assert np.max(np.abs(dem)) <= 10.0 and np.max(np.abs(dem)) > 1.0
    # it follows the 2 Hz sine (with the lag of a 3 Hz position loop)
    sp = ecu["setpoint_position_m"]
    assert np.sqrt(np.mean((meas[:, K.M_POS] - sp) ** 2)) < 0.7 * np.sqrt(np.mean(sp ** 2))
    assert np.corrcoef(meas[:, K.M_POS], sp)[0, 1] > 0.8


# --- the stop on a non-finite state -------------------------------------------------------

UNSTABLE = FAST.with_dict({"screw.screw_inertia_kg_m2": 1e-8, "motor.inertia_kg_m2": 1e-7,
                           "reducer.inertia_kg_m2": 0.0, "sim.substep_s": 1e-3})


def test_a_non_finite_state_stops_every_loop_at_the_same_period():
    prof = make_profile("sine", duration_s=0.3)
    tr = simulate(prof, UNSTABLE, chunk_s=0.01)
    assert not tr.meta["complete"] and 10 < len(tr) < 300
    assert len(simulate(prof, UNSTABLE)) == len(tr)          # chunking does not move it
    nominal = simulate(prof, FAST)
    d = P.drive_of(nominal.measured(), "absolute", FAST)
    for cols in (R.closed_loop(UNSTABLE, d), R.open_loop(UNSTABLE, d),
                 R.mechanics_replay(UNSTABLE, d, nominal["motor_speed_rad_s"])):
        pos = cols["position_m"]
        assert np.isfinite(pos[:len(tr)]).all() and np.isnan(pos[len(tr):]).all()
    cl = R.closed_loop(UNSTABLE, d)
    np.testing.assert_array_equal(cl["current_demand_a"][:len(tr)], tr["current_demand_a"])
    assert np.isnan(cl["current_demand_a"][len(tr):]).all()


# --- one copy of each shared law ----------------------------------------------------------

def reference_pi(e, integ, kp, ki, dt, limit):
    u_un = kp * e + integ
    u = min(max(u_un, -limit), limit)
    if not (u != u_un and e * u_un > 0.0):
        integ += ki * e * dt
    return u, integ


def test_clamped_pi_saturates_and_stops_integrating_outwards():
    # saturated and pushed further out: output at the limit, integral held
    assert clamped_pi(2.0, 9.0, 1.0, 100.0, 1e-3, 10.0) == (10.0, 9.0)
    assert clamped_pi(-2.0, -9.0, 1.0, 100.0, 1e-3, 10.0) == (-10.0, -9.0)
    # saturated but the error pulls back in: integrates
    assert clamped_pi(-2.0, 13.0, 1.0, 100.0, 1e-3, 10.0) == (10.0, 13.0 - 0.2)
    rng = np.random.default_rng(0)
    for e, integ, kp, ki, lim in rng.standard_normal((500, 5)) * [5, 5, 2, 50, 4]:
        assert clamped_pi(e, integ, kp, ki, 1e-3, abs(lim)) == reference_pi(
            e, integ, kp, ki, 1e-3, abs(lim))


@pytest.mark.parametrize("extra", [{}, {"reducer.ratio": 0.3, "motor.inertia_kg_m2": 0.002,
                                        "screw.support_static_friction_nm": 0.1,
                                        "motor.viscous_friction_nm_s": 1e-6}])
def test_plant_and_monitor_share_inertia_and_friction(extra):
    params = PlantParams().with_dict(extra)
    p = param_vector(params)
    mp = M.MonitorParams.from_plant(params)
    m, r, s = params.motor, params.reducer, params.screw
    assert p[K.P_JEQ] == mp.inertia_kg_m2 == equivalent_inertia(params) == pytest.approx(
        (m.inertia_kg_m2 + r.inertia_kg_m2) / r.ratio ** 2 + s.screw_inertia_kg_m2)
    assert p[K.P_CS] == mp.static_friction_nm == static_friction(params) == pytest.approx(
        (m.static_friction_nm + r.static_friction_nm) / r.ratio + s.support_static_friction_nm)
    assert p[K.P_CVISC] == mp.viscous_friction_nm_s == viscous_friction(params)
    assert p[K.P_CN] == viscous_friction(params) / r.ratio
    assert math.isfinite(p[K.P_JEQ]) and p[K.P_JEQ] > 0


def test_plant_sensor_vector_is_public():
    params = FAST.with_dict({"sensors.lvdt_gain": 1.1, "sensors.current_offset_a": 0.3})
    plant = Plant(params)
    np.testing.assert_array_equal(plant.sensor_vector, sensor_vector(params))
    plant.set_params(FAST)
    np.testing.assert_array_equal(plant.sensor_vector, sensor_vector(FAST))
