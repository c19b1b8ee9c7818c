"""The significance test against a calibration's held-out healthy level
(`bench.gap.diagnose`: `significance`, `calibrated_thresholds`, `basis`;
`bench.gap.calibrate.reference_of`), on synthetic residual energies."""

from __future__ import annotations

import math

import pytest

from bench.gap import diagnose as D
from bench.gap import resim as R
from bench.gap.calibrate import heldout_significance, reference_of


class FakeProblem:
    """What `significance` and `heldout_level` read from a Problem: energies given per
    signal (raw and smoothed alike)."""

    def __init__(self, smoothed: dict[str, float], n: int = 10_000, corr: float = 50.0):
        self.sm = {s: smoothed.get(s, 1.0) for s in R.SIGNALS}
        self.n, self.n_fit = n, n // 2
        self.info = {"nominal": {}, "corr_smooth": {s: corr for s in R.SIGNALS}}

    def energies(self, sim, lo, hi):
        return dict(self.sm)

    def energies_smooth(self, sim, lo, hi):
        return dict(self.sm)


def _ref(level: dict[str, float] | None, margin: float = 1.5) -> dict:
    return {"name": "CAL", "level": level, "logs": ["healthy-2"],
            "margin": {s: margin for s in R.SIGNALS} if level else None}


def test_default_path_is_the_plain_threshold():
    p = FakeProblem({"current_a": 3.0})
    default = D.thresholds(p)
    assert D.calibrated_thresholds(default, None) == default
    assert D.calibrated_thresholds(default, _ref(None)) == default
    sig, _, sm = D.significance(p)
    assert sig and sm["current_a"] == 3.0
    assert D.significance(p, None) == D.significance(p)


def test_held_out_level_raises_the_threshold_only_where_it_is_higher():
    p = FakeProblem({"current_a": 3.0})
    default = D.thresholds(p)
    ref = _ref({"current_a": 2.5, "motor_speed_rad_s": 0.5, "position_m": 1.0,
                "encoder_position_m": 1.0})
    thr = D.calibrated_thresholds(default, ref)
    assert thr["current_a"] == pytest.approx(3.75)              # 2.5 x 1.5 > default
    assert thr["motor_speed_rad_s"] == default["motor_speed_rad_s"]   # 0.75 < default
    assert not D.significance(p, ref)[0]                         # 3.0 < 3.75
    assert D.significance(FakeProblem({"current_a": 4.0}), ref)[0]
    # a level on one signal does not hide a gap on another
    assert D.significance(FakeProblem({"current_a": 3.0, "position_m": 9.0}), ref)[0]


def test_the_verdict_line_names_the_calibration_and_the_level():
    p = FakeProblem({"motor_speed_rad_s": 3.0})
    ref = _ref({s: 2.3 if s == "motor_speed_rad_s" else 0.5 for s in R.SIGNALS})
    b = D.basis(ref, p.sm, D.thresholds(p))
    assert b["line"].startswith("judged against calibration CAL: held-out healthy level "
                                "x2.3 on motor_speed_rad_s")
    assert b["threshold"]["motor_speed_rad_s"] == pytest.approx(3.45)
    unknown = D.basis(_ref(None), p.sm, D.thresholds(p))
    assert "unknown" in unknown["line"] and "default threshold applies" in unknown["line"]
    assert unknown["threshold"] == D.thresholds(p)


def test_margin_is_the_statistics_prediction_bound():
    p = FakeProblem({"current_a": 2.0}, n=10_000, corr=50.0)
    lv = D.heldout_level(p)
    assert lv["level"]["current_a"] == 2.0
    want = 1.0 + D.HELDOUT_Z * math.sqrt(2.0) * math.sqrt(2.0 * 50.0 / 10_000)
    assert lv["margin"]["current_a"] == pytest.approx(want)
    # a longer held-out log pins the level down more tightly
    assert D.heldout_level(FakeProblem({}, n=40_000))["margin"]["current_a"] < want


def test_reference_of_a_calibration():
    cal = {"params": {}, "heldout_significance": {
        "known": True, "level": {"current_a": 2.0}, "margin": {"current_a": 1.4},
        "logs": ["h2.npz"], "model": "plant", "encoder": "absolute"}}
    ref = reference_of(cal, "cal.json", "plant", "absolute")
    assert ref["level"] == {"current_a": 2.0} and ref["name"] == "cal.json"
    assert reference_of(cal, "cal.json", "monitoring", "absolute")["level"] is None
    assert reference_of({"params": {}}, "old.json")["level"] is None    # older calibration
    unknown = heldout_significance({"params": {}}, None, [], [])  # type: ignore[arg-type]
    assert unknown["known"] is False and unknown["level"] is None
    assert reference_of({"heldout_significance": unknown}, "c")["level"] is None


@pytest.mark.parametrize("bad", [{"current_a": "x"}, "oops", {"current_a": float("nan")},
                                 {"current_a": True}])
def test_a_bad_stored_level_or_energy_is_a_one_line_error(bad):
    """A hand-edited calibration whose held-out level, margin or energy is not a number per
    signal is refused when it is read, naming the file and the field (it raised a bare
    TypeError after the whole diagnosis before)."""
    from bench import BenchError
    good = {"known": True, "level": {"current_a": 2.0}, "margin": {"current_a": 1.4},
            "energy": {"current_a": 1.5}, "logs": [], "model": "plant", "encoder": "absolute"}
    assert reference_of({"heldout_significance": good}, "c.json")["energy"] == {"current_a": 1.5}
    for key in ("level", "margin", "energy"):
        with pytest.raises(BenchError, match=f"c.json: heldout_significance.{key} must map"):
            reference_of({"heldout_significance": {**good, key: bad}}, "c.json")
