"""`bench gap --nominal CAL.json` on the thesis plant's path attaches the calibration's
controller to a log whose metadata names none (and to the --holdout log), and says so in
one line; the bench's ECU and a log's own controller are left alone."""

from __future__ import annotations

import argparse
import json

import numpy as np

from bench.cli.gap import _attach_controller
from bench.signals.trace import Trace

CASCADE = {"source": "encoder", "kp_pos": 2e5, "ki_pos": 1.2e6, "kp_spd": 0.44,
           "ki_spd": 8.2, "speed_limit_rad_s": 300.0, "current_limit_a": 20.0,
           "every_periods": 2, "position_integral_zero_hz": 1.0,
           "speed_integral_zero_hz": 3.0}


def _log(meta=None):
    return Trace({"t_s": np.arange(4) * 1e-3}, dict(meta or {}))


def _args(tmp_path, controller):
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"params": {}, "controller": controller}))
    return argparse.Namespace(nominal=str(cal)), json.loads(cal.read_text())


def test_the_calibrations_cascade_is_attached_to_both_logs(tmp_path):
    ctrl = {"method": "fitted-cascade", "doc": "...", "cascade": CASCADE}
    log, hold = _log(), _log()
    line = _attach_controller(*_args(tmp_path, ctrl), log, hold)
    assert line.startswith("re-simulated under the controller identified by calibration "
                           "cal.json: fitted-cascade: position PI on the encoder")
    assert "every 2 SYNC period(s)" in line and "\n" not in line
    assert log.meta["controller"] == ctrl and hold.meta["controller"] == ctrl


def test_measured_current_is_attached_without_calling_it_a_controller(tmp_path):
    ctrl = {"method": "measured-current", "doc": "the logged current drives the plant"}
    log = _log()
    line = _attach_controller(*_args(tmp_path, ctrl), log, None)
    assert line == ("re-simulated as calibration cal.json handles the controller: "
                    "measured-current (the logged current drives the plant)")
    assert log.meta["controller"]["method"] == "measured-current"


def test_the_bench_ecu_and_no_calibration_change_nothing(tmp_path):
    log = _log()
    assert _attach_controller(*_args(tmp_path, {"method": "bench-ecu"}), log, None) is None
    assert _attach_controller(argparse.Namespace(nominal=None), None, log, None) is None
    assert "controller" not in log.meta


def test_a_log_naming_its_own_controller_keeps_it(tmp_path):
    own = {"method": "measured-current"}
    log = _log({"controller": own})
    ctrl = {"method": "fitted-cascade", "cascade": CASCADE}
    line = _attach_controller(*_args(tmp_path, ctrl), log, None)
    assert line == ("re-simulated under the controller its metadata names "
                    "(measured-current), not the calibration's (fitted-cascade)")
    assert log.meta["controller"] is own
