"""`bench hums report` and `bench gap` on the Cranfield sample's 25 Hz cycles,
CLI in-process: the report with neither a calibration nor a baseline (model-free
indexes, every model-based section "not available" with its reason), with a baseline,
with a calibration whose model stays above the noise floor (then `bench calibrate` wrote
the healthy baseline from its calibration runs and both commands judge against it and
say so), and the reference choice on its own (`bench.rig.fallback.choose`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sample_data import cranfield_folder

from bench import BenchError
from bench.bus.logs import load_trace
from bench.cli import main
from bench.rig import fallback as FB

SPALL = "load=40_run=1_group=51.parquet"      # spalling stage 5, run 1, first cycle
HELD = "load=40_run=3_group=61.parquet"       # healthy run 3: never in a baseline here
# calibration logs: three cycles of healthy runs 1 and 2 (a baseline needs 3 cycles a
# load, its thresholds two runs, one held out at a time)
FIT = [f"load=40_run={r}_group={g}.parquet" for r, gs in ((1, (51, 52, 53)), (2, (56, 57, 58)))
       for g in gs]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return cranfield_folder(tmp_path_factory.mktemp("rigreport"))


@pytest.fixture(scope="module")
def calibrated(data):
    """`bench calibrate --actuator cranfield` on 6 healthy cycles, 1 held out."""
    cal = data / "cal.json"
    assert main(["calibrate", *[str(data / "n" / f) for f in FIT], "--actuator", "cranfield",
                 "--holdout", str(data / "n" / HELD), "-o", str(cal)]) == 0
    return cal


def _report(args, out):
    code = main(["hums", "report", *map(str, args), "--out", str(out)])
    js = json.loads((out / "indexes.json").read_text())
    return code, js[0], (out / "report.html").read_text()


def test_report_without_a_reference_gives_model_free_indexes_and_reasons(data, tmp_path,
                                                                          capsys):
    code, js, page = _report([data / "s" / SPALL], tmp_path)
    assert code == 3                               # written, but no verdict: UNKNOWN
    assert js["verdict"] == "UNKNOWN" and "no reference" in js["judged_against"]
    mf = js["model_free"]
    assert set(mf) == {"extend", "retract", "dwell", "all"}
    assert mf["extend"]["samples"] + mf["retract"]["samples"] + mf["dwell"]["samples"] == 324
    assert mf["retract"]["current_rms_a"] > mf["extend"]["current_rms_a"] > 0   # 40 kgf
    sec = js["sections"]
    assert sec["model-free indexes: position error per direction"] == "available"
    assert "needs a calibration" in sec["calibrated model: Cp, mean error (eq. 6.4-6.5)"]
    assert "needs a healthy baseline" in sec["healthy baseline: phase indexes, features, verdict"]
    assert "needs setpoint_speed_rad_s, mode" in sec[
        "thesis monitoring model: Cp, Ci, peak ratio, harmonics (eq. 6.3-6.7)"]
    assert "motor_angle_rad" in sec["lost motion (encoder against LVDT)"]
    assert "not available" in page and "data:image/png;base64," in page
    assert (tmp_path / "summary.txt").read_text().startswith(SPALL + ": UNKNOWN")
    assert "error: no verdict" in capsys.readouterr().err


def test_report_against_a_baseline_names_it(data, tmp_path):
    base = data / "base.json"
    code, js, page = _report([data / "s" / SPALL, "--baseline", base], tmp_path / "s")
    assert code == 0 and js["verdict"] == "DEGRADED"
    assert "runs 1,2, load 40" in js["judged_against"] and "base.json" in js["judged_against"]
    b = js["baseline"]
    assert b["flagged"] == 1 and b["effects"] == {"periodic": 1}
    assert "runs 1,2" in b["verdicts"][0]["baseline"]
    rows = {(r["phase"], r["index"]) for r in b["phase_indexes"]}
    assert ("out", "current_constant") in rows and ("in", "position_error_peak") in rows
    assert "Against the healthy baseline" in page and "periodic" in page
    code, js, _ = _report([data / "n" / HELD, "--baseline", base], tmp_path / "h")
    assert code == 0 and js["verdict"] == "HEALTHY"       # held-out healthy run 3
    assert "needs a calibration" in js["sections"]["calibrated model: Ci, peak ratio (eq. 6.6-6.7)"]


def test_calibrate_writes_the_baseline_when_above_the_floor(calibrated, capsys):
    cal = json.loads(calibrated.read_text())
    assert cal["reaches_noise_floor"] is False
    assert any(n.startswith("no model of this family reaches 2 x the noise floor on the "
                            "held-out logs: diagnose against a baseline") for n in cal["notes"])
    ref = cal["baseline"]
    assert ref["file"] == "cal.baseline.json" and ref["loads"]["40"]["runs"] == [1, 2]
    assert ref["loads"]["40"]["cycles"] == 6 and ref["loads"]["40"]["thresholds"]
    assert any("thresholds from calibration runs 1,2 only" in n for n in cal["notes"])
    base = FB.B.Baseline.load(calibrated.parent / ref["file"])
    assert base.lead_mm == pytest.approx(5.0) and base.load_unit == "kgf"
    from bench.rig.features import FEATURES
    assert set(base.thresholds["40"]["thresholds"]) == set(FEATURES)
    assert HELD.split(".")[0] not in " ".join(base.for_load(40).cycles)   # held out stays out


def test_gap_and_report_judge_against_the_calibration_baseline(data, calibrated, tmp_path,
                                                              capsys):
    capsys.readouterr()
    assert main(["gap", str(data / "s" / SPALL), "--nominal", str(calibrated)]) == 0
    out = capsys.readouterr().out
    line = out.splitlines()[1]
    assert line.startswith("model above the noise floor on held-out healthy logs (x")
    assert "judged against the healthy baseline" in line and "(runs 1,2, load 40 kgf, 6 cycles)" in line
    assert "FLAGGED" in out and "periodic" in out
    js_path = tmp_path / "g.json"
    assert main(["gap", str(data / "n" / HELD), "--nominal", str(calibrated), "--json",
                 str(js_path)]) == 0
    js = json.loads(js_path.read_text())
    assert js["against"] == "baseline" and js["flagged"] == 0 and "runs 1,2" in js["baseline"]
    code, rep, page = _report([data / "s" / SPALL, "--nominal", calibrated], tmp_path / "r")
    assert code == 0 and rep["verdict"] == "DEGRADED"
    assert rep["judged_against"] == line
    assert set(rep["model"]["indexes"]) == {"cp", "mean_error_m", "ci", "peak_ratio"}
    assert np.isfinite(rep["model"]["indexes"]["ci"])
    assert "does not reach the noise floor" in page
    # forced onto the model: its verdict, and it says so
    code, rep, _ = _report([data / "s" / SPALL, "--nominal", calibrated, "--against", "model"],
                           tmp_path / "m")
    assert "--against model: judged against the calibrated model" in rep["judged_against"]
    assert rep["baseline"] is None and any("RMS" in r for r in rep["reasons"])


def test_reference_choice_and_a_log_set_that_cannot_make_a_baseline(data, tmp_path):
    cal = {"reaches_noise_floor": True, "floor_factor": 2.0,
           "holdout_summary": {"position_m": {"ratio_max": 1.4}}}
    ref = FB.choose(cal, "c.json")
    assert ref.kind == "model" and ref.line().startswith(
        "model within 2 x the noise floor on held-out healthy logs (x1.4)")
    with pytest.raises(BenchError, match="wrote no healthy baseline"):
        FB.choose(cal, "c.json", against="baseline")
    # one cycle per run: no set of repeated cycles a baseline can be built from
    above = {"reaches_noise_floor": False, "floor_factor": 2.0,
             "holdout_summary": {"current_a": {"ratio_max": 2.9}}}
    notes = FB.baseline_for_calibration(above, [data / "n" / HELD, data / "n" / SPALL],
                                        str(tmp_path / "c.json"), 5.0)
    assert above["baseline"] is None and "at least 3" in above["baseline_not_available"]
    assert "verdicts stay against the model" in notes[0]
    ref = FB.choose(above, tmp_path / "c.json")
    assert ref.kind == "model" and "(x2.9), and no healthy baseline (" in ref.line()
    assert not (tmp_path / "c.baseline.json").exists()


def test_cycles_that_do_not_repeat_one_setpoint_make_no_baseline(data):
    from bench.rig.baseline import build
    cycles = [c for f in FIT[:4] for c in FB.log_cycles(load_trace(data / "n" / f), f)]
    cycles[0].setpoint_mm = cycles[0].setpoint_mm * 0.8 + 4.0   # a shorter stroke
    with pytest.raises(BenchError, match="do not repeat one set-point profile"):
        build(cycles)


def test_a_log_of_several_cycles_with_its_load_in_newtons(data, calibrated, tmp_path):
    """Three cycles in one trace, no split keys: cycles from the set-point, the logged load
    (N) converted to the kgf of the baseline `bench calibrate` wrote (its logs' import map
    gives the unit)."""
    from bench.signals.trace import Trace
    parts = [Trace.load(data / "s" / f"load=40_run=1_group={g}.parquet") for g in (51, 52, 53)]
    cols = {k: np.concatenate([t[k] for t in parts])
            for k in ("setpoint_position_m", "position_m", "current_a", "load_force_n")}
    cols["t_s"] = np.arange(len(cols["current_a"])) * 0.04
    Trace(cols, {"source": "three cycles"}).save(tmp_path / "three.npz")
    code, js, _ = _report([tmp_path / "three.npz", "--baseline",
                           calibrated.parent / "cal.baseline.json"], tmp_path / "r")
    b = js["baseline"]
    assert code == 0 and b["cycles"] == 3 and b["load"] == 40.0
    assert any("judged at the baseline's 40" in n for n in b["notes"])
    assert js["verdict"] == "DEGRADED" and b["flagged"] >= 2


def rig_log(path: Path, seconds: float = 13.0, current: bool = True) -> Path:
    """A 25 Hz rig table: a 20 -> 140 mm trapezoid, position lagging, current."""
    from bench.signals.trace import Trace
    t = np.arange(int(round(seconds / 0.04))) * 0.04
    sp = np.interp(t, [0, 0.3, 5.3, 8.3, 13.3], [0.02, 0.02, 0.14, 0.14, 0.02])
    cols = {"t_s": t, "setpoint_position_m": sp, "position_m": np.roll(sp, 2)}
    if current:
        cols["current_a"] = 0.3 + 0.1 * np.sign(np.gradient(sp))
    Trace(cols).save(path)
    return path


def test_an_output_directory_that_cannot_be_made_is_one_line_before_the_work(tmp_path,
                                                                              capsys):
    # was FileNotFoundError at the catch-all (rc 1) after the analysis
    log = rig_log(tmp_path / "rig.npz")
    (tmp_path / "afile").write_text("")
    assert main(["hums", "report", str(log), "--out", str(tmp_path / "afile" / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: --out: cannot write into {tmp_path / 'afile' / 'x'}: "
                   f"{tmp_path / 'afile'} is not a directory"]


def rig_calibration(path: Path, scored: tuple[str, ...] = ("position_m", "current_a")) -> Path:
    """A calibration of `bench calibrate --actuator` (a DC drive, the generic model's
    values of tests/integration/test_rig_calibrate.py) that reaches the noise floor on
    healthy logs scored on `scored`."""
    from bench.sim.rigmodel import EXTRA
    vals = {**EXTRA, "mass_kg": 400.0, "force_per_a_n": 1500.0, "coulomb_n": 120.0,
            "viscous_n_s_per_m": 1500.0, "current_offset_a": 0.1, "kp_1_s": 12.0,
            "kv_a_s_per_m": 60.0, "ki_a_per_m": 900.0, "feedforward": 0.8,
            "current_limit_a": 4.0, "current_tau_s": 0.0}
    score = {s: {"rms": 1.0, "noise_floor": 1.0, "ratio": 1.0} for s in scored}
    path.write_text(json.dumps({
        "model": "generic nut-level model (bench.sim.rigmodel)", "actuator": "dc",
        "actuator_description": {"name": "dc", "motor_kind": "dc_current_loop"},
        "method": "fit-gains", "sample_period_s": 1e-3, "values": vals,
        "fit_logs": ["h1"], "fit_scores": [score], "holdout_summary": {},
        "reaches_noise_floor": True, "floor_factor": 2.0}))
    return path


def test_a_log_too_short_for_the_model_says_how_long_it_is_and_must_be(tmp_path, capsys):
    # was "error: fidelity coefficient: empty window" (rc 2)
    log = rig_log(tmp_path / "two.npz", seconds=0.08)
    cal = rig_calibration(tmp_path / "cal.json")
    code, js, _ = _report([log, "--nominal", cal], tmp_path / "out")
    why = ("not available: the log is too short: 2 position sample(s) over 0.04 s; the "
           "model's noise floor needs at least 5 samples, 0.16 s at its 40 ms rate")
    assert code == 3 and js["verdict"] == "UNKNOWN"
    assert js["sections"]["calibrated model: Cp, mean error (eq. 6.4-6.5)"] == why
    assert why in capsys.readouterr().err
    assert main(["gap", str(log), "--nominal", str(cal)]) == 2
    assert why.replace("not available: ", "") in capsys.readouterr().err


def test_a_log_without_a_signal_the_model_was_scored_on_gets_no_verdict(tmp_path, capsys):
    # was HEALTHY (rc 0) on position alone, with Ci "not available"
    log = rig_log(tmp_path / "nocur.npz", current=False)
    code, js, _ = _report([log, "--nominal", rig_calibration(tmp_path / "cal.json")],
                          tmp_path / "out")
    assert code == 3 and js["verdict"] == "UNKNOWN"
    assert js["reasons"][-1] == ("the calibrated model's verdict needs every signal its "
                                 "healthy logs were scored on; not judged: current_a (the "
                                 "log has no current_a)")
    assert js["model"]["rms_ratio"].keys() == {"position_m"}
    assert "not judged: current_a" in capsys.readouterr().err
    # a calibration scored on position only judges the same log
    cal = rig_calibration(tmp_path / "cal_pos.json", scored=("position_m",))
    code, js, _ = _report([log, "--nominal", cal], tmp_path / "out2")
    assert code == 0 and js["verdict"] in ("HEALTHY", "DEGRADED")


def test_gap_json_has_one_schema_against_the_model_and_the_baseline(data, calibrated,
                                                                     tmp_path):
    """`bench gap --json` of one log judged against the calibrated model and against the
    healthy baseline: the same top-level keys (`GAP_KEYS`), a `verdict` of
    `Verdict.to_json()`, `against` and `reference` saying which; and each verdict is the
    one `bench hums report` gives the log against the same reference."""
    from bench.gap.result_json import GAP_KEYS
    docs = {}
    for against in ("model", "baseline"):
        path = tmp_path / f"{against}.json"
        assert main(["gap", str(data / "s" / SPALL), "--nominal", str(calibrated),
                     "--against", against, "--json", str(path)]) == 0
        docs[against] = json.loads(path.read_text())
        code, rep, _ = _report([data / "s" / SPALL, "--nominal", calibrated, "--against",
                                against], tmp_path / f"r_{against}")
        assert docs[against]["verdict"]["level"] == rep["verdict"], against
    m, b = docs["model"], docs["baseline"]
    assert set(m) == set(b) == set(GAP_KEYS)
    assert set(m["verdict"]) == set(b["verdict"]) == {"level", "code", "effect", "reasons",
                                                      "reference"}
    assert (m["against"], b["against"]) == ("model", "baseline")
    assert m["reference"] == m["verdict"]["reference"] != b["reference"]
    assert "healthy baseline" in b["reference"] and m["ranking"] and b["ranking"] is None
    assert b["verdicts"] and m["verdicts"] is None
    assert b["verdict"]["level"] == "DEGRADED" and b["verdict"]["effect"] == "periodic"


def test_a_flagged_cycle_and_its_log_carry_one_level(data, tmp_path, capsys):
    """A deviation from the healthy baseline is DEGRADED (past the threshold; the rig
    baseline has no warning or failure level) for the cycle in `bench rig assess --json`,
    and for the cycle and its log in `bench gap --json` and `bench hums report`."""
    log, base = data / "s" / SPALL, data / "base.json"
    assess = tmp_path / "assess.json"
    assert main(["rig", "assess", str(log), "--baseline", str(base), "--json", str(assess),
                 "-q"]) == 0
    cycle = json.loads(assess.read_text())
    assert [c["flagged"] for c in cycle] == [True]
    gap = tmp_path / "gap.json"
    assert main(["gap", str(log), "--baseline", str(base), "--json", str(gap), "-q"]) == 0
    g = json.loads(gap.read_text())
    code, rep, page = _report([log, "--baseline", base], tmp_path / "r")
    assert code == 0
    levels = {"rig assess cycle": cycle[0]["level"], "gap cycle": g["verdicts"][0]["level"],
              "gap log": g["verdict"]["level"], "report cycle": rep["baseline"]["verdicts"][0]["level"],
              "report log": rep["verdict"]}
    assert set(levels.values()) == {"DEGRADED"}, levels
    assert "WARNING" not in gap.read_text()
    assert (tmp_path / "r" / "summary.txt").read_text().startswith(SPALL + ": DEGRADED")
    capsys.readouterr()
