"""The flight profile over the bus: the plant computes the aero load (with its
gusts) and Archard wear behind the bus; a lockstep run equals the in-process one."""

from __future__ import annotations

import numpy as np
import pytest
from bus_helpers import BUS_KINDS, module_bus_env

from bench.ecu import run_over_bus
from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate
from plant_rt.params import PlantParams

# DBC quanta, and how many of them the bus run may differ by. The ECU computes from
# quantised sensors; with wear 1e6 times faster than real use the preload changes every
# period, so the motion's quantum-level differences feed back through the wear: measured
# 0.9 quanta of position and 33 quanta (3.3 mA) of current at most (aero alone: 14, wear
# alone: 41, neither: 9 quanta of current).
QUANT = {"position_m": (1e-8, 20), "current_a": (1e-4, 100), "motor_speed_rad_s": (1e-4, 100),
         "current_demand_a": (1e-4, 100), "load_force_n": (2.0, 20)}


@pytest.fixture(scope="module", params=BUS_KINDS)
def bus_env(request, tmp_path_factory):
    yield from module_bus_env(request, tmp_path_factory)


def test_flight_with_aero_load_and_wear_over_the_bus_equals_in_process(bus_env):
    values = {"drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic",
              "load.kind": "aero", "wear.kind": "archard", "wear.acceleration": 1e6,
              "effects.preload_n": 2000.0}
    prof = make_profile("flight", duration_s=30.0, seed=5)
    dur = 2.5                       # the ground test and the start of the take-off
    tr = run_over_bus(prof, values=values, pace="sync", settings=bus_env.cfg, duration_s=dur)
    params = PlantParams().with_dict(values)
    ref = simulate(prof, params, duration_s=dur)
    assert tr.meta["complete"] and len(tr) == len(ref) == 2500
    for col, (q, n) in QUANT.items():
        err = np.max(np.abs(tr[col] - ref[col]))
        assert err <= n * q, (col, err / q)
    # the load cell carries the hinge load and the gusts (1 kN std), not zero
    assert np.std(tr["load_force_n"]) > 100.0
    assert ref["preload_n"][-1] < 2000.0            # the wear acted in the run
