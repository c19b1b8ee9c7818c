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
from bench.harness import simulate
from bench.profiles import make_profile


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
    cal.write_text(json.dumps({"model": "generic-dc", "x": 1}))
    assert calibration_file(str(cal)) == {"model": "generic-dc", "x": 1}
