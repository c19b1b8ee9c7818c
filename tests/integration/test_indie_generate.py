"""The independent actuator in-process (indie_plant.generate) and a tiny blind benchmark on
it (`bench gap-bench --generator independent`)."""

from __future__ import annotations

import json
import math

import numpy as np

from bench.cli import main
from bench.gap import indiebench as IB
from indie_plant.controller import Cascade
from indie_plant.generate import simulate
from indie_plant.params import IndieParams


def _sine(n: int = 2000):
    t = np.arange(n) * 1e-3
    return 0.5e-3 * np.sin(2 * math.pi * 2.0 * t), np.zeros(n), np.ones(n)


def test_runs_are_seeded_and_the_own_cascade_holds_its_demand_two_periods():
    sp, spd, mode = _sine()
    p = IndieParams()
    a = simulate(p, sp, spd, mode, seed=4)
    b = simulate(p, sp, spd, mode, seed=4)
    c = simulate(p, sp, spd, mode, seed=5)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["current_a"], c["current_a"])
    dem = a["current_demand_a"]
    assert np.array_equal(dem[0::2], dem[1::2])           # 2 ms sample time
    assert np.sqrt(np.mean((a["position_m"] - sp)[500:] ** 2)) < 0.3e-3
    ecu = simulate(p, sp, spd, mode, controller=IB.bench_ecu_cascade(), seed=4)
    assert not np.array_equal(ecu["current_demand_a"][0::2], ecu["current_demand_a"][1::2])
    assert Cascade.own(p).every_periods == 2


def test_injected_effects_act_in_the_independent_physics():
    sp, spd, mode = _sine()
    p = IndieParams().with_dict({"noise": 0.0})
    base = simulate(p, sp, spd, mode)
    worn = simulate(p.with_dict({"backlash_m": 80e-6, "preload_n": 0.0}), sp, spd, mode)
    # lost motion: the encoder travel leads the LVDT by about half the clearance at reversals
    lead = worn["motor_angle_rad"] * p.travel_per_rad - worn["position_m"]
    lead0 = base["motor_angle_rad"] * p.travel_per_rad - base["position_m"]
    assert np.ptp(lead[500:]) - np.ptp(lead0[500:]) > 50e-6      # ~80 um of clearance
    rough = simulate(p.with_dict({"friction_scale": 3.0}), sp, spd, mode)
    # x3 friction: (2 x 0.14 N m) / kt ~ 0.3 A more while sliding
    def along(c):      # the current's part along the motion: friction, not inertia
        return np.mean(c["current_a"][500:] * np.sign(c["motor_speed_rad_s"][500:]))
    assert along(rough) - along(base) > 0.15


def test_gap_bench_on_the_independent_generator_smoke(tmp_path, capsys):
    out = tmp_path / "indie.json"
    rc = main(["gap-bench", "--generator", "independent", "--cases", "2", "--seed", "11",
               "--workers", "1", "--log-s", "2", "--effects", "backlash,friction",
               "--json", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "Held-out healthy log" in text and "top-1, single effects" in text
    js = json.loads(out.read_text())
    assert js["generator"] == "independent" and len(js["results"]) == 2
    seeds = {js["calibration"]["seed"], js["heldout_healthy"]["seed"]}
    case_seeds = {c.noise_seed for c in IB.make_cases(2, 11)}
    assert len(seeds) == 2 and not seeds & case_seeds
    for sig in ("current_a", "motor_speed_rad_s", "position_m", "encoder_position_m"):
        assert math.isfinite(js["heldout_healthy"]["signals"][sig]["ratio"])
    assert all(r["verdict"] for r in js["results"])
