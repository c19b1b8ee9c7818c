"""Controller identification for a log run under a controller the bench does not know
(`bench.gap.calibrate` controller=fitted-cascade / measured-current)."""

import math

import pytest

from bench import BenchError
from bench.cli import main
from bench.gap import indiebench as IB
from bench.gap.blind import Case
from bench.gap.calibrate import calibrate
from indie_plant.controller import Cascade as OwnCascade

LOG_S = 3.0


def test_the_own_controller_is_identified_and_closes_the_model_loop():
    log = IB.generate(Case(-1, "nominal", [], 4242), True, LOG_S, "own")
    cal = calibrate(log, IB.datasheet_model(), controller="fitted-cascade")
    ctrl = cal["controller"]
    assert ctrl["method"] == "fitted-cascade" and "demand" in ctrl["fitted_to"]
    assert len(ctrl["structures_tried"]) == 6
    c, own = ctrl["cascade"], OwnCascade.own(IB.NOMINAL)
    assert c["source"] == "encoder" and c["every_periods"] == own.every_periods
    for k in ("kp_pos", "ki_pos", "kp_spd", "ki_spd"):
        assert math.isclose(c[k], getattr(own, k), rel_tol=1e-6), k
    # the identified loop reproduces a held-out healthy log better than the bench's ECU
    # (worst ratio on this 3 s log: 115 against 202 with the datasheet's first-order LVDT
    # conditioner in the model, 96 against 203 before it)
    model = IB.datasheet_model().with_dict(cal["params"])
    mine = IB.heldout_residual(model, 7, LOG_S, "own", identified=ctrl)
    ecu = IB.heldout_residual(model, 7, LOG_S, "own")
    worst = {k: max(d["ratio"] for d in r.values()) for k, r in (("id", mine), ("ecu", ecu))}
    assert worst["id"] < 0.6 * worst["ecu"]


def test_bad_controller_choices_are_one_line_errors(capsys):
    with pytest.raises(BenchError, match="controller must be one of"):
        calibrate(IB.generate(Case(-1, "nominal", [], 1), False, LOG_S), controller="pid")
    rc = main(["gap-bench", "--identify", "measured-current"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --identify is for --generator independent --controller own"]
