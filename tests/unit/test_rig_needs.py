"""Signal requirements: the reasons a sparse log gets, and the actuator
description's checks. (That the declarations equal the consumers' own constants is in
tests/integration/test_rig_calibrate.py: it imports the compiled modules.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import BenchError
from bench.gap.needs import availability, missing
from bench.rig.actuator import from_dict, load, model_values
from bench.signals.trace import Trace


def sparse(dt: float = 0.04) -> Trace:
    t = np.arange(50) * dt
    return Trace({"t_s": t, "setpoint_position_m": 0.01 * t, "position_m": 0.01 * t,
                  "current_a": np.ones_like(t)})


def test_a_25_hz_log_with_set_point_position_and_current():
    av = availability(sparse())
    assert av["calibrate: thesis plant"] == (
        "not available: needs mode, motor_speed_rad_s, motor_angle_rad, samples every "
        "1 ms (the log: every 40 ms)")
    assert av["HUMS index: lost motion"] == ("not available: needs motor_angle_rad, "
                                             "motor_speed_rad_s")
    for ok in ("calibrate: generic model, cascade fitted",
               "rig gap: localisation (signal, regime, direction, position)",
               "rig HUMS index: Ci, peak ratio (eq. 6.6-6.7)"):
        assert av[ok] is None
    assert missing(sparse(1e-3), ("sync", "current_a|motor_speed_rad_s")) == []
    assert missing(sparse(1e-3), ("load_force_n|current_demand_a",)) == [
        "load_force_n or current_demand_a"]


def test_the_shipped_cranfield_description():
    a = load("cranfield")
    assert a.motor_kind == "stepper_chopper" and a.structure == "unknown"
    assert a.values["lead_m"] == 0.005 and a.values["stroke_m"] == 0.12
    assert "RM1605" in a.sources["lead_m"] and a.values["holding_torque_nm"] == 4.6
    assert all(v is None for k, v in model_values(a).items() if k != "sample_period_s")
    assert from_dict(json.loads(json.dumps(a.to_dict()))) == a      # round trip


@pytest.mark.parametrize("entry, msg", [
    ({"motor_kind": "hydraulic"}, "motor_kind must be one of"),
    ({"motor_kind": "dc_current_loop", "lead_mm": 5}, "unknown entry lead_mm"),
    ({"motor_kind": "dc_current_loop", "lead_m": 5}, r"lead_m = 5 m is outside"),
    ({"motor_kind": "dc_current_loop", "lead_m": "five"}, "must be a number in m"),
    ({"motor_kind": "dc_current_loop", "controller": {"structure": "pid"}},
     "controller structure must be one of"),
])
def test_bad_descriptions_are_clear(entry, msg):
    with pytest.raises(BenchError, match=msg):
        from_dict(entry)


def test_derived_nut_values():
    a = from_dict({"motor_kind": "bldc_current_loop", "lead_m": 0.005, "ratio": 2.0,
                   "efficiency": 0.9, "torque_constant_nm_per_a": 0.5,
                   "moving_mass_kg": 10.0, "motor_inertia_kg_m2": 1e-4,
                   "screw_inertia_kg_m2": 2e-5})
    v = model_values(a)
    w = 2 * np.pi / 0.005
    assert v["mass_kg"] == pytest.approx(10.0 + (2e-5 + 4e-4) * w * w)     # eq. 5.12 at the nut
    assert v["force_per_a_n"] == pytest.approx(0.5 * 2.0 * 0.9 * w)
    assert v["kp_1_s"] is None


@pytest.mark.parametrize("sign", [0, 0.5, -0.3])
def test_load_sign_other_than_plus_or_minus_one_is_refused(sign):
    # it was accepted in [-1, 1] and a 0 became +1 in the re-simulation (`or 1.0`)
    with pytest.raises(BenchError, match=r"load_sign must be \+1 or -1 .* got "):
        from_dict({"motor_kind": "dc_current_loop", "load_sign": sign}, "act.json")


def test_load_sign_minus_one_flips_the_load_and_unknown_is_plus_one():
    from bench.rig.rigcal import load_sign
    assert load_sign(from_dict({"motor_kind": "dc_current_loop", "load_sign": -1})) == -1.0
    assert load_sign(from_dict({"motor_kind": "dc_current_loop"})) == 1.0


@pytest.mark.parametrize("name, content, msg", [
    ("act.json", None, "act.json: a directory, not an actuator description"),
    ("act.json", b"\x91\xb6garbage", r"act.json: not valid JSON \('utf-8' codec"),
    ("act.toml", b"\xff\x00garbage", r"act.toml: not valid TOML \('utf-8' codec"),
    ("act.json", b"[" * 100_000, r"act.json: not an actuator description \(nested too deep"),
    ("act.json", b'{"motor_kind": "dc_current_loop", "sources": 5}',
     "act.json: sources must be a text or a list of texts, got 5"),
], ids=["directory", "json-not-utf8", "toml-not-utf8", "nested-too-deep", "sources-5"])
def test_an_unreadable_actuator_description_is_one_line(tmp_path, name, content, msg):
    # found by fuzzing `bench calibrate --actuator`: exit 1 with
    # IsADirectoryError, UnicodeDecodeError, RecursionError, TypeError
    path = tmp_path / name
    if content is None:
        path.mkdir()
    else:
        path.write_bytes(content)
    with pytest.raises(BenchError, match=msg):
        load(path)
