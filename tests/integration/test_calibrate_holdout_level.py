"""`bench calibrate LOG --holdout LOG` stores the calibrated model's held-out healthy
level (heldout_significance) and `bench gap --nominal CAL.json` judges against it, saying
so in one line; without --holdout the level is unknown and the default test applies."""

from __future__ import annotations

import json

import pytest

from bench.cli import main
from bench.gap.resim import FAST
from bench.profiles.maneuvers import compact
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("heldout")
    base = PlantParams().with_dict({**FAST, "sensors.noise": True})
    for name, seed in (("fit", 31), ("held", 32), ("judged", 33)):
        simulate(compact(), base.with_dict({"sensors.noise_seed": seed})).measured().save(
            d / f"{name}.npz")
    simulate(compact(), base.with_dict({"sensors.noise_seed": 34,
                                        "effects.friction_scale": 3.0})).measured().save(
        d / "worn.npz")
    return d


def _calibrate(d, out, *extra):
    return main(["calibrate", str(d / "fit.npz"), "--params", "effects.friction_scale",
                 "-o", str(d / out), *extra])


def test_holdout_level_is_stored_and_used(logs, capsys):
    assert _calibrate(logs, "cal.json", "--holdout", str(logs / "held.npz")) == 0
    out = capsys.readouterr().out
    assert "held-out healthy level" in out
    hs = json.loads((logs / "cal.json").read_text())["heldout_significance"]
    assert hs["known"] and hs["logs"] == [str(logs / "held.npz")]
    assert hs["paths"] == [str((logs / "held.npz").resolve())]
    assert set(hs["level"]) == {"current_a", "motor_speed_rad_s", "position_m",
                                "encoder_position_m"}
    assert all(0.0 < v < 10.0 for v in hs["level"].values())
    assert all(1.0 < m < 5.0 for m in hs["margin"].values())   # 4 s log: wide
    assert main(["gap", str(logs / "judged.npz"), "--nominal", str(logs / "cal.json"),
                 "--effects", "backlash", "--workers", "1", "-q",
                 "--json", str(logs / "gap.json")]) == 0
    out = capsys.readouterr().out
    assert "judged against calibration cal.json: held-out healthy level x" in out
    ja = json.loads((logs / "gap.json").read_text())["localisation"]["significance"][
        "judged_against"]
    for s, lv in hs["level"].items():
        assert ja["threshold"][s] >= lv * hs["margin"][s] - 1e-12


def test_the_held_out_log_gives_the_verdict_its_model_form_term(logs, capsys):
    """`bench gap --nominal` fits the verdict's candidate on the calibration's held-out
    healthy log (stored path) and says so in `selection.model_form`; a calibration
    without one leaves the verdict's fit as it is."""
    assert _calibrate(logs, "cal_m.json", "--holdout", str(logs / "held.npz")) == 0
    assert _calibrate(logs, "cal_m0.json") == 0
    out = {}
    for cal in ("cal_m", "cal_m0"):
        assert main(["gap", str(logs / "worn.npz"), "--nominal", str(logs / f"{cal}.json"),
                     "--effects", "friction", "--workers", "1", "-q",
                     "--json", str(logs / f"gap_{cal}.json")]) == 0
        out[cal] = json.loads((logs / f"gap_{cal}.json").read_text())
    capsys.readouterr()
    mf = out["cal_m"]["localisation"]["selection"]["model_form"]
    assert mf["healthy_log"] == str((logs / "held.npz").resolve())
    assert "friction_scale" in mf["departure_u"]        # (and the nut friction share)
    assert "model_form" not in out["cal_m0"]["localisation"]["selection"]
    assert out["cal_m"]["verdict"]["effect"] == out["cal_m0"]["verdict"]["effect"]


def test_a_moved_held_out_log_is_said_not_found(logs, capsys):
    """A calibration whose held-out healthy log has gone (moved, another machine): the
    diagnosis runs without the model-form term and says so in one line."""
    import shutil
    moved = logs / "moved"
    moved.mkdir()
    shutil.copy(logs / "held.npz", moved / "held.npz")
    assert _calibrate(logs, "cal_mv.json", "--holdout", str(moved / "held.npz")) == 0
    shutil.rmtree(moved)
    capsys.readouterr()
    assert main(["gap", str(logs / "worn.npz"), "--nominal", str(logs / "cal_mv.json"),
                 "--effects", "friction", "--workers", "1", "-q",
                 "--json", str(logs / "gap_mv.json")]) == 0
    err = capsys.readouterr().err
    notes = [ln for ln in err.splitlines() if "is not found" in ln]
    assert len(notes) == 1 and str((moved / "held.npz").resolve()) in notes[0], err
    js = json.loads((logs / "gap_mv.json").read_text())
    assert "model_form" not in js["localisation"]["selection"]


def test_without_holdout_the_level_is_unknown(logs, capsys):
    assert _calibrate(logs, "cal0.json") == 0
    hs = json.loads((logs / "cal0.json").read_text())["heldout_significance"]
    assert hs["known"] is False and hs["level"] is None
    assert main(["gap", str(logs / "judged.npz"), "--nominal", str(logs / "cal0.json"),
                 "--effects", "backlash", "--workers", "1", "-q"]) == 0
    assert ("judged against calibration cal0.json: its held-out healthy level is unknown"
            in capsys.readouterr().out)


def test_the_calibration_log_cannot_be_its_own_holdout(logs, capsys):
    assert _calibrate(logs, "bad.json", "--holdout", str(logs / "fit.npz")) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --holdout")


def test_the_calibration_declares_the_friction_split_and_gap_follows_it(logs, capsys):
    """`bench calibrate --friction-split unknown` stores the model's declaration; `bench
    gap --nominal` uses it (the JSON and the summary state it) unless --friction-split
    says otherwise."""
    assert _calibrate(logs, "cal_u.json", "--friction-split", "unknown") == 0
    assert "friction split: unknown" in capsys.readouterr().out
    assert json.loads((logs / "cal_u.json").read_text())["friction_split"] == "unknown"
    for extra, want in (((), "unknown"), (("--friction-split", "model"), "the model's")):
        assert main(["gap", str(logs / "judged.npz"), "--nominal", str(logs / "cal_u.json"),
                     "--effects", "backlash", "--workers", "1", "-q", *extra,
                     "--json", str(logs / "gap_u.json")]) == 0
        assert f"friction split: {want}" in capsys.readouterr().out
        model = json.loads((logs / "gap_u.json").read_text())["localisation"]["model"]
        assert model["friction_split"].startswith(want)
