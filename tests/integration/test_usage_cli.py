"""`bench usage` in-process on saved traces: per run and per actuator, JSON, figures, and
one-line errors for bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench.cli import main
from bench.signals.trace import Trace

DT = 1e-3


def _trace(path, serial: str, load_n: float) -> None:
    n = 2001
    t = np.arange(n) * DT
    rev = 2.0 * t                                       # 2 screw rev/s, 4 rev
    Trace({"t_s": t, "motor_angle_rad": rev * 2 * math.pi / 0.25,
           "load_force_n": np.full(n, load_n), "current_a": np.full(n, 2.0),
           "motor_speed_rad_s": np.full(n, 2 * 2 * math.pi / 0.25)},
          {"period_s": DT, "actuator_serial": serial}).save(path)


def test_usage_per_run_and_per_actuator(tmp_path, capsys):
    a, b, c = tmp_path / "a.npz", tmp_path / "b.npz", tmp_path / "c.npz"
    _trace(a, "11", 3000.0)
    _trace(b, "11", 6000.0)
    _trace(c, "12", 1000.0)
    out = tmp_path / "u.json"
    assert main(["usage", str(a), str(b), str(c), "--by-actuator", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "actuator 11" in text and "actuator 12" in text
    doc = json.loads(out.read_text())
    assert [r["actuator_serial"] for r in doc["runs"]] == ["11", "11", "12"]
    acc = doc["actuators"]["11"]
    assert acc["runs"] == 2
    assert acc["life_consumed"] == pytest.approx(
        doc["runs"][0]["life_consumed"] + doc["runs"][1]["life_consumed"], rel=1e-12)
    # by hand: 4 rev at 3 kN and 4 rev at 6 kN against C_a = 22 kN (less the hysteresis's
    # half width, 2e-4 rev, per run)
    revs = 4.0 - 2e-4
    d = revs * (3000.0 ** 3 + 6000.0 ** 3) / (22000.0 ** 3 * 1e6)
    assert acc["life_consumed"] == pytest.approx(d, rel=1e-9)
    assert acc["fast_s"] == pytest.approx(4.002)        # 40 mm/s: fast, every sample
    # figures: one per run, one per actuator
    assert main(["usage", str(c), "--plot", str(tmp_path / "fig")]) == 0
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == [
        "actuator_12_usage.png", "c_usage.png"]


@pytest.mark.parametrize("args, message", [
    (["nothing.log"], "no such file"),
    (["/dev/null"], "/dev/null: not a regular file (a device or a pipe: give - "),
    (["--preload-n", "nan", "X"], "--preload-n must be a finite"),
    (["--json", "out.txt", "X"], "unknown suffix"),
    (["--load-rating-n", "0", "X"], "--load-rating-n must be a finite number of newtons > 0"),
    (["--set", "usage.bogus=1", "X"], "expected NAME=VALUE"),
    (["--set", "usage.load_hysteresis_n=-5", "X"], "below its minimum"),
])
def test_bad_input_is_one_line(tmp_path, capsys, args, message):
    x = tmp_path / "x.npz"
    _trace(x, "1", 0.0)
    args = [str(x) if a == "X" else (str(tmp_path / a) if a.endswith(".txt") else a)
            for a in args]
    assert main(["usage", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0]


def test_a_run_without_a_signal_reports_not_available_not_zero(tmp_path, capsys):
    # a table with set-point and position only: travel, reversals, I2t, RMS current and
    # life consumed were printed and written as 0 (only stderr said "those quantities
    # are 0")
    t = np.arange(326) * 0.04
    sp = np.interp(t, [0, 0.3, 5.3, 8.3, 13.3], [0.02, 0.02, 0.14, 0.14, 0.02])
    Trace({"t_s": t, "setpoint_position_m": sp, "position_m": sp}).save(tmp_path / "r.npz")
    out = tmp_path / "u.json"
    assert main(["usage", str(tmp_path / "r.npz"), "--json", str(out)]) == 0
    text = capsys.readouterr().out.splitlines()
    row = text[1].split()     # run actuator runs time rev travel revers. pos load Fm L10 life I2t
    assert row[4:7] == ["n/a"] * 3 and row[7] == "1" and row[11:13] == ["n/a"] * 2
    assert "r.npz: not available (needs motor_angle_rad): screw_revolutions, nut_travel_m, " \
           "reversals" in text
    assert any(line.startswith("r.npz: not available (needs current_a): i2t_a2s, "
                               "current_rms_a") for line in text)
    run = json.loads(out.read_text())["runs"][0]
    for key in ("nut_travel_m", "reversals", "i2t_a2s", "current_rms_a", "life_consumed",
                "screw_revolutions", "load_spectrum_rev"):
        assert run[key] is None, key
    assert run["not_available"]["i2t_a2s"] == "needs current_a"
    assert run["not_available"]["life_consumed"] == "needs motor_angle_rad and load_force_n"
    assert run["position_cycles"] == 1.0 and run["duration_s"] == pytest.approx(13.04)
