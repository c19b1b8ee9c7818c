"""`bench calibrate --controller` on the thesis plant's path, and `bench gap --nominal
CAL.json` re-simulating a log under the controller that calibration identified (issue
11: a log run under the actuator's own controller, written by the independent
generator)."""

from __future__ import annotations

import json

import pytest

from bench.cli import main
from bench.gap import indiebench as IB
from bench.gap.blind import Case

LOG_S = 2.0


@pytest.fixture(scope="module")
def indie(tmp_path_factory):
    d = tmp_path_factory.mktemp("ctrl")
    for name, seed in (("fit", 11), ("judged", 12)):
        IB.generate(Case(-1, "nominal", [], seed), True, LOG_S, "own").save(d / f"{name}.npz")
    (d / "datasheet.json").write_text(IB.datasheet_model().to_json())
    return d


def _cal(d, out, *extra):
    return main(["calibrate", str(d / "fit.npz"), "--nominal", str(d / "datasheet.json"),
                 "--params", "effects.friction_scale", "-o", str(d / out), *extra])


def _gap(d, cal, capsys):
    assert main(["gap", str(d / "judged.npz"), "--nominal", str(d / cal), "--effects",
                 "backlash", "--workers", "1", "-q", "--json", str(d / f"gap_{cal}")]) == 0
    return capsys.readouterr().out, json.loads((d / f"gap_{cal}").read_text())


def test_gap_resimulates_under_the_calibrations_identified_controller(indie, capsys):
    assert _cal(indie, "own.json", "--controller", "fitted-cascade") == 0
    out = capsys.readouterr().out
    assert "controller: fitted-cascade: position PI on the encoder" in out
    cal = json.loads((indie / "own.json").read_text())
    assert cal["controller"]["method"] == "fitted-cascade"
    assert cal["controller"]["cascade"]["source"] == "encoder"
    assert cal["base_params"]["screw.lead_m"] == pytest.approx(IB.NOMINAL.lead_m)
    assert _cal(indie, "ecu.json") == 0
    capsys.readouterr()
    assert json.loads((indie / "ecu.json").read_text())["controller"]["method"] == "bench-ecu"

    out, own = _gap(indie, "own.json", capsys)
    lines = [ln for ln in out.splitlines() if ln.startswith("re-simulated under")]
    assert len(lines) == 1 and lines[0].startswith(
        "re-simulated under the controller identified by calibration own.json: fitted-cascade")
    assert own["controller"]["cascade"] == cal["controller"]["cascade"]
    out, ecu = _gap(indie, "ecu.json", capsys)
    assert "re-simulated under" not in out and ecu["controller"] is None
    # the log was run under its own controller: re-simulated under the identified one,
    # the encoder's residual is far below the bench ECU's (121x against 3e4x its floor)
    e_own = own["localisation"]["significance"]["energy"]["encoder_position_m"]
    e_ecu = ecu["localisation"]["significance"]["energy"]["encoder_position_m"]
    assert e_own < 0.05 * e_ecu
