"""`bench gap --nominal FILE` reads FILE once: the model, the calibration's reference,
its friction split and its controller all come from that one reading (before, the file
was read six times, so a calibration rewritten during a run could mix two versions); a
generic calibration without its actuator description is a one-line error."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import bench.gap.diagnose as D
from bench.cli import main
from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate


class _Stop(Exception):
    pass


def test_the_nominal_file_is_read_once_and_feeds_every_use(tmp_path, monkeypatch):
    log = tmp_path / "log.npz"
    simulate(make_profile("step", duration_s=0.05)).save(log)
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"params": {"effects.friction_scale": 1.2},
                               "base_params": {}, "friction_split": "unknown"}))
    reads = []
    real = Path.read_text

    def counting(self, *a, **kw):
        if self == cal:
            reads.append(1)
        return real(self, *a, **kw)

    seen = {}

    def fake(trace, hold, nominal, options, **kw):
        seen.update(nominal=nominal, options=options)
        raise _Stop("stopped before the fits")

    monkeypatch.setattr(Path, "read_text", counting)
    monkeypatch.setattr(D, "diagnose", fake)
    assert main(["gap", str(log), "--nominal", str(cal), "--quiet"]) != 0
    assert len(reads) == 1
    assert seen["nominal"].effects.friction_scale == pytest.approx(1.2)
    assert seen["options"].friction_split == "unknown"


def test_a_generic_calibration_without_its_actuator_is_one_line(tmp_path, capsys):
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"model": "generic-dc"}))
    rc = main(["gap", str(tmp_path / "any.npz"), "--nominal", str(cal)])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0] == (
        f"error: {cal}: a calibration of another actuator needs its "
        "\"actuator_description\" (bench calibrate --actuator writes it)")


@pytest.mark.parametrize("text", ["{not json", json.dumps({"params": {}}), "[1, 2]"])
def test_the_rig_report_refuses_what_is_not_a_generic_calibration(tmp_path, text):
    from bench import BenchError
    from bench.rig.hums import calibration_file
    cal = tmp_path / "cal.json"
    cal.write_text(text)
    with pytest.raises(BenchError, match="not a calibration of `bench calibrate --actuator`"):
        calibration_file(str(cal))
    with pytest.raises(BenchError, match="no such calibration"):
        calibration_file(str(tmp_path / "missing.json"))
    cal.write_text(json.dumps(GOOD))
    assert calibration_file(str(cal)) == GOOD


GOOD = {"model": "generic-dc", "actuator_description": {"motor_kind": "dc_current_loop"},
        "method": "fit-gains", "sample_period_s": 1e-3,
        "values": {k: 1.0 for k in ("mass_kg", "force_per_a_n", "coulomb_n",
                                    "viscous_n_s_per_m", "current_offset_a", "kp_1_s",
                                    "kv_a_s_per_m", "ki_a_per_m", "feedforward",
                                    "current_limit_a", "current_tau_s")}}


@pytest.mark.parametrize("change, msg", [
    ({"values": None}, 'no "values" object'),
    ({"values": {**GOOD["values"], "mass_kg": "heavy"}},
     "values.mass_kg must be a finite number, got 'heavy'"),
    ({"values": {k: v for k, v in GOOD["values"].items() if k != "kp_1_s"}},
     "values.kp_1_s must be a finite number, got nothing"),
    ({"method": "guess"}, "method must be one of"),
    ({"sample_period_s": 0}, "sample_period_s must be a number of seconds > 0"),
])
def test_a_generic_calibration_with_a_bad_field_is_one_line(tmp_path, capsys, change, msg):
    # these reached the CLI's catch-all (ValueError, KeyError: 'values', rc 1)
    from bench import BenchError
    from bench.rig.hums import calibration_file
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({k: v for k, v in {**GOOD, **change}.items() if v is not None}))
    assert main(["gap", str(tmp_path / "any.npz"), "--nominal", str(cal)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {cal}: {msg}")
    with pytest.raises(BenchError, match=msg):
        calibration_file(str(cal))


def test_a_baseline_given_as_nominal_says_to_pass_it_as_baseline(tmp_path, capsys):
    # was "unknown parameter group 'thresholds'"
    from bench import BenchError
    from bench.rig.hums import calibration_file
    base = tmp_path / "base.json"
    base.write_text(json.dumps({"format": "bench-rig-baseline/1", "thresholds": {},
                                "loads": []}))
    assert main(["gap", str(tmp_path / "any.npz"), "--nominal", str(base)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: {base}: a healthy baseline (bench rig baseline), not a calibration or "
        f"parameter file: bench gap and bench hums report take it with --baseline {base}")
    with pytest.raises(BenchError, match="take it with --baseline"):
        calibration_file(str(base))


def test_a_nominal_json_nested_too_deep_is_one_line(tmp_path, capsys):
    # found by fuzzing: RecursionError reached the catch-all (exit 1)
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000)
    assert main(["gap", str(tmp_path / "any.npz"), "--nominal", str(deep)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: {deep}: not a calibration or parameter JSON (nested too deep to read)")


def test_an_empty_nominal_object_is_refused_not_read_as_the_thesis_values(tmp_path, capsys):
    # the bug: `--nominal` of a file holding `{}` ran on the thesis values and exited 0,
    # as if the user had given no --nominal (a truncated or placeholder calibration)
    from bench import BenchError
    from bench.gap.inputs import load_nominal
    empty = tmp_path / "empty.json"
    empty.write_text("{}")
    with pytest.raises(BenchError, match="holds no parameter"):
        load_nominal(empty)
    assert main(["gap", str(tmp_path / "any.npz"), "--nominal", str(empty)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: {empty}: an empty JSON object holds no parameter: give a calibration "
        "(bench calibrate) or a parameter file, or leave --nominal out for the thesis values")
