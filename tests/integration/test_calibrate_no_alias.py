"""Calibrating the independent actuator's datasheet model on one of its healthy logs
keeps the lead and the LVDT gain at their description (the log fixes only their product;
the compliance under the logged load belongs to the contact stiffness). Before, the
stiffness was profiled after a least squares of the rest, which took the lead x gain
alias for a softer nut: the 4 mm lead went to 3.34 mm and the LVDT gain to 1.197, 18 and
9 prior sd from the description, and a later LVDT gain fault was read as a lead x0.78."""

from __future__ import annotations

from bench.gap import indiebench as IB
from bench.gap.blind import Case
from bench.gap.calibrate import calibrate, default_names


def test_a_healthy_calibration_keeps_lead_and_lvdt_gain_at_the_description():
    log = IB.generate(Case(-1, "nominal", [], 2025 + IB.CALIBRATION_SEED_OFFSET), True,
                      10.0, "ecu")
    cal = calibrate(log, IB.datasheet_model(), default_names(log))
    z = cal["prior_distance_sd"]
    assert abs(z["screw.lead_m"]) < 1.0 and abs(z["sensors.lvdt_gain"]) < 1.0, z
    assert all(abs(v) < 2.0 for v in z.values()), z
    assert not cal["at_bound"]
    lo, hi = cal["ci95"]["screw.lead_m"]
    assert lo < 4e-3 < hi
    assert cal["gap_after"]["heldout_part"]["total"] < 1.5
