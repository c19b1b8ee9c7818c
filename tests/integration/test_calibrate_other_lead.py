"""`bench calibrate` on an actuator outside the thesis' ranges: a 10 mm lead (the
thesis' 5 mm, the calibration's range 4-6 mm). Before the fix the start and prior were
clipped to 6 mm, and the calibration compensated with the LVDT gain, friction, kt and a
current offset on their bounds (held-out gap 21x); the range now moves to the model's
value (docs/gap.md, "Calibration")."""

from __future__ import annotations

import json

import pytest

from bench.gap.blind import MEASURED, excitation
from bench.signals.trace import Trace
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


def test_a_10_mm_lead_is_calibrated_at_10_mm(tmp_path, capsys):
    from bench.cli import main
    model = PlantParams().with_dict({"screw.lead_m": 10e-3})
    run = model.with_dict({"sensors.noise": True, "sensors.noise_seed": 7,
                           "drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic"})
    tr = simulate(excitation(5.0), run)
    log = Trace({c: tr[c] for c in ("t_s", *MEASURED)}, {}).save(tmp_path / "lead10.npz")
    nominal = tmp_path / "nominal10.json"
    js = model.to_json()
    nominal.write_text(js if isinstance(js, str) else json.dumps(js))
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(log), "--nominal", str(nominal), "-o", str(out)]) == 0
    cal = json.loads(out.read_text())
    assert cal["params"]["screw.lead_m"] == pytest.approx(10e-3, rel=0.01)
    assert cal["params"]["sensors.lvdt_gain"] == pytest.approx(1.0, abs=0.01)
    assert cal["gap_after"]["heldout_part"]["total"] < 2.0
