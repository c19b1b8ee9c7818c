"""`bench rig inject` on the shipped Cranfield sample (tests/data/cranfield_sample, load
40 kgf): baseline and thresholds from healthy runs 1-2, faults injected into held-out
runs 3-4. A large fault of each kind (8 sigma of the healthy spread) is flagged in every
cycle and named as its kind; the unmodified held-out cycles are not flagged."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.cli import main

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "cranfield_sample"
HEALTHY = SAMPLE / "normal_load40_runs1-4.csv.xz"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("inject")
    rc = main(["rig", "inject", str(HEALTHY), "--calibrate-runs", "1,2", "--holdout-runs",
               "3,4", "--lead-mm", "5", "--sizes", "8", "--out", str(out)])
    assert rc == 0
    return out, json.loads((out / "inject.json").read_text())


def _cell(res, kind):
    return res["loads"]["40"]["kinds"][kind]["8"]


def test_writes_the_report_and_the_figure(report):
    out, res = report
    assert (out / "inject.png").stat().st_size > 10_000
    md = (out / "inject.md").read_text()
    assert "friction" in md and "backlash" in md and "bench rig inject" in md
    assert res["calibrate_runs"] == [1, 2] and res["holdout_runs"] == [3, 4]
    assert res["loads"]["40"]["holdout"] == {**res["loads"]["40"]["holdout"],
                                            "cycles": 10, "flagged": 0}


# cycles of 10 named right at 8 sigma (measured with the current features: the 22 mm
# bump leaks into the lead-periodic projection in one cycle, which is then named
# periodic, also a position-locked effect; docs/rig-results.md, injected faults)
NAMED_RIGHT = {"friction": 10, "localised": 9, "periodic": 10, "backlash": 10}


@pytest.mark.parametrize("kind", ["friction", "localised", "periodic", "backlash"])
def test_a_large_fault_is_flagged_and_named_right(report, kind):
    _, res = report
    c = _cell(res, kind)
    assert c["cycles"] == 10 and c["flagged"] == 10
    assert c["named_right"] >= NAMED_RIGHT[kind], c["effects"]


def test_the_localised_fault_is_placed_where_it_was_put(report):
    _, res = report
    at = res["loads"]["40"]["scales"]["at_mm"]
    assert abs(_cell(res, "localised")["location_mm"] - at) < 5.0


@pytest.mark.parametrize("flag,value,message", [
    ("--sizes", "0,1", "--sizes: every size must be a finite number > 0"),
    ("--kinds", "friction,wear", "--kinds: unknown wear"),
    # a bump centred outside the stroke was injected nowhere: "0 % / 0 %, not reached"
    ("--at-mm", "9999", "--at-mm 9999: outside the measured stroke of load 40 (19.9 to "
                        "140.0 mm)"),
    ("--at-mm", "nan", "--at-mm must be a finite position in mm, got nan"),
    # which list has no cycle (it said: "of the calibration runs [1, 2] or of the held-out
    # runs [3, 4]")
    ("--calibrate-runs", "8,9", "no cycle of the calibration runs 8,9 (--calibrate-runs); "
                                "the healthy cycles read are of run(s) 1,2,3,4"),
])
def test_bad_input_is_one_line(tmp_path, capsys, flag, value, message):
    rc = main(["rig", "inject", str(HEALTHY), "--calibrate-runs", "1,2", "--holdout-runs",
               "3,4", "--lead-mm", "5", "--kinds", "localised", "--sizes", "4", flag, value,
               "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.startswith("error: ") and message in err
    assert len(err.splitlines()) == 1


def test_out_must_be_a_directory(tmp_path, capsys):
    (tmp_path / "f").write_text("")
    rc = main(["rig", "inject", str(HEALTHY), "--calibrate-runs", "1,2", "--holdout-runs",
               "3,4", "--lead-mm", "5", "--out", str(tmp_path / "f")])
    assert rc == 2 and "it is not a directory" in capsys.readouterr().err


def test_the_lead_is_required(tmp_path, capsys):
    rc = main(["rig", "inject", str(HEALTHY), "--calibrate-runs", "1,2", "--holdout-runs",
               "3,4", "--out", str(tmp_path / "o")])
    assert rc == 2 and "needs the screw's lead" in capsys.readouterr().err


def test_a_constant_current_offset_does_not_reach_the_position_locked_features():
    """A friction offset in amperes is removed in amperes before the localised
    scan and the lead-periodic projection, so both read exactly what they read without it
    (before, the offset divided by the per-sample spread leaked into them and injected
    friction was named localised); a play shifts the out/in hysteresis (reversal)."""
    from bench.rig import baseline as B
    from bench.rig import inject as I
    from bench.rig.cycles import read_cycles
    from bench.rig.features import cycle_features
    cyc = read_cycles(HEALTHY)
    lb = B.build([c for c in cyc if c.run in (1, 2)]).for_load(40.0)
    c = next(c for c in cyc if c.run == 3)
    f0 = cycle_features(lb, c, 5.0)
    f1 = cycle_features(lb, I.friction(c, 0.4), 5.0)
    for k in ("localised", "periodic"):
        assert f1.scores[k] == pytest.approx(f0.scores[k], rel=1e-9, abs=1e-9)
    assert f1.scores["level"] > f0.scores["level"] + 3.0
    f2 = cycle_features(lb, I.backlash(c, 2.0), 5.0)
    assert f2.scores["reversal"] > 5 * max(f0.scores["reversal"], 1.0)
