"""The gap page shows what a reader can read: a shrink not measured reads n/a (not
None), one that rounds to zero from below reads 0.0 (not -0.0), a log without a
fundamental says so (not "f0 = nan Hz"), and a friction factor that is not the fitted
scale says what it is."""

from __future__ import annotations

import math

import pytest

from bench.gap.report import _size_notes, ranking_table
from bench.gap.summary import f0_text

pytestmark = pytest.mark.unit


def _row(shrink: float | None) -> dict:
    return {"rank": 1, "effect": "viscous", "params": {}, "heldout_shrink_pct": shrink,
            "gap_before": {"normalised": 40.6}, "gap_after": {"normalised": 40.6},
            "score": {"bic": 1773.8}}


@pytest.mark.parametrize(("shrink", "shown"), [(None, "n/a"), (-0.04, "0.0"),
                                               (-0.06, "-0.1"), (99.96, "100.0")])
def test_shrink_cell(shrink, shown):
    js = {"ranking": [_row(shrink)], "localisation": {}}
    cell = ranking_table(js).rows[0][3]
    assert cell == shown
    assert "None" not in cell and cell != "-0.0"


def test_f0_text():
    assert f0_text(1.9999999999999982) == "f0 = 2 Hz"
    assert f0_text(float("nan")) == "no fundamental"
    assert f0_text(None) == "no fundamental"
    assert "nan" not in f0_text(math.inf)


def test_friction_factor_says_what_it_is():
    js = {"finding": {"effects": [
        {"line": "backlash 49.99 um [49.88, 50.1], axial lost motion 70.8 um",
         "size": {"kind": "lost_motion_m", "value": 7e-5}},
        {"line": "friction x2.38 [2.22, 2.56] (every level together (Coulomb, static))",
         "size": {"kind": "factor", "value": 2.38,
                  "how": "friction work over the log's motion, fitted / model's"}}]}}
    (note,) = _size_notes(js)
    assert note.text.startswith("friction x2.38 [2.22, 2.56]: friction work over")
    assert "backlash" not in note.text
    assert _size_notes({"finding": {"effects": []}}) == []
