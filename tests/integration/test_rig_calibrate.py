"""Calibration of another actuator: synthetic logs from the generic model with
known values, an unknown cascade whose gains are recovered, the measured current driving
the mechanics, a stepper's limits said, and `bench gap` against the calibration."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import BenchError
from bench.cli import main
from bench.rig import rigcal as RC
from bench.rig.actuator import from_dict
from bench.signals.trace import Trace
from bench.sim import rigmodel as RM

TRUE = {**RM.EXTRA, "mass_kg": 400.0, "force_per_a_n": 1500.0, "coulomb_n": 120.0,
        "viscous_n_s_per_m": 1500.0, "current_offset_a": 0.1, "kp_1_s": 12.0,
        "kv_a_s_per_m": 60.0, "ki_a_per_m": 900.0, "feedforward": 0.8,
        "current_limit_a": 4.0, "current_tau_s": 0.0}
# a BLDC drive whose mechanics are known (kt 1.19 N m/A direct, 5 mm lead: 1500 N/A),
# controller unknown
KNOWN = {"motor_kind": "bldc_current_loop", "lead_m": 0.005, "ratio": 1.0,
         "efficiency": 1.0, "torque_constant_nm_per_a": 1500.0 * 0.005 / (2 * np.pi),
         "moving_mass_kg": 400.0, "motor_inertia_kg_m2": 0.0,
         "coulomb_friction_n": 120.0, "viscous_friction_n_s_per_m": 1500.0,
         "current_offset_a": 0.1,
         "controller": {"structure": "unknown", "sample_period_s": 1e-3,
                        "current_loop_tau_s": 0.0}}


def synthetic(seed: int, load_n: float, dt: float = 0.04, stepper: bool = False,
              **change: float) -> Trace:
    """A 13 s trapezoid (20 -> 140 mm) from the generic model, sampled every `dt`, with
    20 um and 5 mA of white noise."""
    t = np.arange(int(round(13.0 / dt))) * dt
    sp = np.interp(t, [0, 0.3, 5.3, 8.3, 13.3], [0.02, 0.02, 0.14, 0.14, 0.02])
    v = {**TRUE, **change}
    x, i = RM.closed_loop(np.array([v[k] for k in RM.THETA]), stepper, t, sp,
                          np.full(len(t), load_n), 1e-3, 0.02)
    rng = np.random.default_rng(seed)
    return Trace({"t_s": t, "setpoint_position_m": sp,
                  "position_m": x + rng.normal(0, 20e-6, len(t)),
                  "current_a": i + rng.normal(0, 5e-3, len(t)),
                  "load_force_n": np.full(len(t), load_n)}, {"source": f"synthetic {seed}"})


def test_unknown_cascade_gains_recovered_at_25_hz():
    cal = RC.calibrate_rig([synthetic(1, 200.0), synthetic(2, -200.0)], from_dict(KNOWN),
                           [synthetic(3, 0.0)])
    assert cal["method"] == "fit-gains" and "cascade" in cal["method_text"]
    assert set(cal["fitted"]) == {"kp_1_s", "kv_a_s_per_m", "ki_a_per_m", "feedforward",
                                  "current_limit_a"}
    v = cal["values"]
    assert v["kp_1_s"] == pytest.approx(12.0, rel=0.1)
    assert v["kv_a_s_per_m"] == pytest.approx(60.0, rel=0.1)
    assert v["ki_a_per_m"] == pytest.approx(900.0, rel=0.25)
    assert v["feedforward"] == pytest.approx(0.8, abs=0.05)
    # the limit is never reached (largest current ~0.35 A): it is only bounded below
    assert v["current_limit_a"] > 0.3
    held = cal["holdout_summary"]
    assert held["position_m"]["noise_floor"] == pytest.approx(20e-6, rel=0.25)
    assert held["position_m"]["ratio_max"] < 1.3 and held["current_a"]["ratio_max"] < 1.3
    assert cal["reaches_noise_floor"] is True


def test_measured_current_drives_the_mechanics():
    desc = {**KNOWN, "moving_mass_kg": "unknown", "coulomb_friction_n": "unknown"}
    logs = [synthetic(s, f, dt=0.002) for s, f in ((4, 200.0), (5, -200.0))]
    cal = RC.calibrate_rig(logs, from_dict(desc), [synthetic(6, 0.0, dt=0.002)],
                           "measured-current")
    assert cal["method"] == "measured-current" and "measured current" in cal["method_text"]
    assert set(cal["fitted"]) == {"mass_kg", "coulomb_n"}
    assert cal["values"]["mass_kg"] == pytest.approx(400.0, rel=0.15)
    assert cal["values"]["coulomb_n"] == pytest.approx(120.0, rel=0.15)
    assert list(cal["holdout_summary"]) == ["position_m"]


def test_a_stepper_is_said_what_the_model_cannot_represent():
    gains = {"position_kp_1_s": 12.0, "speed_kp_a_s_per_m": 60.0, "speed_ki_a_per_m": 900.0,
             "speed_feedforward": 0.8, "current_limit_a": 4.0}
    desc = {**KNOWN, "motor_kind": "stepper_chopper",
            "controller": {**KNOWN["controller"], **gains}}
    with pytest.raises(BenchError, match="needs a drive with a current loop.*stepper_chopper"):
        RC.calibrate_rig([synthetic(1, 200.0, stepper=True)], from_dict(desc), (),
                         "measured-current")
    cal = RC.calibrate_rig([synthetic(1, 200.0, stepper=True)], from_dict(desc))
    # a stepper has no torque constant: its force per ampere is identified
    assert cal["method"] == "described" and cal["fitted"] == ["force_per_a_n"]
    assert cal["values"]["force_per_a_n"] == pytest.approx(1500.0, rel=0.1)
    assert any("load angle" in n and "chopper" in n for n in cal["notes"])
    assert cal["fit_scores"][0]["current_a"]["ratio"] < 1.3     # |i| + offset, as logged


def test_missing_set_point_and_current_are_not_available():
    tr = synthetic(1, 0.0)
    del tr.columns["setpoint_position_m"], tr.columns["current_a"]
    with pytest.raises(BenchError, match="not available: needs current_a"):
        RC.calibrate_rig([tr], from_dict(KNOWN))


def test_cli_calibrate_then_gap_finds_a_localised_resistance(tmp_path, capsys):
    for name, tr in (("h1", synthetic(1, 200.0)), ("h2", synthetic(2, -200.0)),
                     ("h3", synthetic(3, 0.0)),
                     ("spall", synthetic(7, 200.0, bump_n=200.0, bump_at_m=0.08))):
        tr.save(tmp_path / f"{name}.npz")
    (tmp_path / "act.json").write_text(json.dumps(KNOWN))
    assert main(["calibrate", str(tmp_path / "h1.npz"), str(tmp_path / "h2.npz"),
                 "--actuator", str(tmp_path / "act.json"), "--holdout",
                 str(tmp_path / "h3.npz"), "-o", str(tmp_path / "cal.json")]) == 0
    out = capsys.readouterr().out
    assert "the controller is unknown: a generic position/speed cascade" in out
    assert "held-out position_m" in out and "noise floor" in out
    assert "calibrate: thesis plant: not available: needs mode, motor_speed_rad_s" in out
    assert main(["gap", str(tmp_path / "spall.npz"), "--nominal",
                 str(tmp_path / "cal.json"), "--json", str(tmp_path / "gap.json")]) == 0
    out = capsys.readouterr().out
    assert "verdict: localised_resistance" in out
    js = json.loads((tmp_path / "gap.json").read_text())
    best = js["ranking"][0]
    assert best["values"]["bump_at_m"] == pytest.approx(0.08, abs=2e-3)
    assert js["indexes"]["peak_ratio"] > 1.3


def test_needs_declarations_are_the_consumers_own():
    from bench.gap.needs import MONITOR_DRIVE, PLANT_RESIM
    from bench.gap.problem import NEEDED
    from bench.hums.monitor import NOMINAL_DRIVE
    assert PLANT_RESIM == NEEDED and MONITOR_DRIVE == NOMINAL_DRIVE


GAINS = {"position_kp_1_s": 12.0, "speed_kp_a_s_per_m": 60.0, "speed_ki_a_per_m": 900.0,
         "speed_feedforward": 0.8, "current_limit_a": 4.0}
DESCRIBED = {**KNOWN, "controller": {**KNOWN["controller"], **GAINS}}


def test_a_held_out_signal_that_could_not_be_scored_is_said():
    # a held-out log without current was scored on position alone and nothing said so
    held = synthetic(3, 0.0)
    del held.columns["current_a"]
    cal = RC.calibrate_rig([synthetic(1, 200.0)], from_dict(DESCRIBED), [held])
    assert cal["method"] == "described" and list(cal["holdout_summary"]) == ["position_m"]
    assert cal["holdout_not_scored"] == [{"log": "synthetic 3", "signal": "current_a",
                                          "reason": "the log has no current_a",
                                          "scored": ["position_m"]}]
    assert ("held-out synthetic 3: current_a not scored (the log has no current_a): only "
            "position_m judged on it") in cal["notes"]


@pytest.mark.parametrize("copy", [False, True])
def test_a_held_out_log_that_is_a_fitted_one_is_refused(tmp_path, capsys, copy):
    synthetic(1, 200.0).save(tmp_path / "h1.npz")
    held = tmp_path / "h1.npz"
    if copy:                                   # the same bytes under another name
        held = tmp_path / "again.npz"
        held.write_bytes((tmp_path / "h1.npz").read_bytes())
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(tmp_path / "h1.npz"), "--actuator", "cranfield",
                 "--holdout", str(held), "-o", str(cal)]) == 2
    err = capsys.readouterr().err
    assert f"--holdout {held} is the same {'content' if copy else 'file'} as the fitted " \
           f"log {tmp_path / 'h1.npz'}" in err and not cal.exists()
    assert main(["calibrate", str(tmp_path / "h1.npz"), str(held), "--actuator",
                 "cranfield", "-o", str(cal)]) == 2
    err = capsys.readouterr().err
    # refused before the command (`outputs.check_io`): the same file, or its bytes again
    assert (f"{held} are one file, given twice" if not copy else
            f"{held} hold the same bytes") in err, err


def test_a_log_too_short_for_a_noise_floor_is_refused():
    # a 2-sample log was calibrated with rc 0 and NaN ratios
    short = synthetic(1, 0.0)
    short.columns = {k: v[:3] for k, v in short.columns.items()}
    with pytest.raises(BenchError, match=r"synthetic 1: calibration \(described\) not "
                       r"available: the log is too short: 3 position sample\(s\) over 0.08 s; "
                       r"the model's noise floor needs at least 5 samples, 0.16 s"):
        RC.calibrate_rig([short], from_dict(DESCRIBED))


def test_the_gap_on_a_log_without_current_ranks_no_current_effect_and_says_so():
    # current_offset was ranked (and fitted) on a log without current, and the
    # "no significant gap" did not say current was not judged
    from bench.rig import riggap as RG
    cal = RC.calibrate_rig([synthetic(1, 200.0)], from_dict(DESCRIBED))
    log = synthetic(3, 0.0)
    del log.columns["current_a"]
    js = RG.diagnose_rig(log, cal, from_dict(DESCRIBED), ("current_offset", "inertia"))
    assert [r["effect"] for r in js["ranking"]] == ["inertia"]
    assert js["not_available"] == {
        "current_offset": "not available: needs current_a (the log has no current_a)"}
    assert js["judged_on"] == ["position_m"]
    assert js["not_judged"] == {"current_a": "the log has no current_a"}
    assert "judged on position_m only; not judged: current_a (the log has no current_a)" \
        in RG.text(js).splitlines()[-1]
