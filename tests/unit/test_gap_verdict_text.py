"""The blind checks' verdict column says what the diagnosis concluded: a fit whose
held-out shrink is below the rule's minimum is the verdict "unexplained", and the table
must not print the closest fit's finding as if it were the verdict."""

from __future__ import annotations

import pytest

from bench.gap.blind import Case, Truth, score

pytestmark = pytest.mark.unit


def _js(verdict: str) -> dict:
    line = "friction x1.79 [1.68, 1.92] (Coulomb and static levels)"
    return {
        "verdict": verdict,
        "ranking": [{"effect": "friction_levels", "chosen": True, "heldout_shrink_pct": 31.0,
                     "params": {"friction_levels_scale": {"value": 1.79}}}],
        "finding": {"line": line, "families": "friction",
                    "effects": [{"family": "friction", "size": ["factor", 1.79]}]},
        "localisation": {"selection": {"chosen": "friction_levels",
                                       "heldout_shrink_pct": 31.0, "min_shrink_pct": 50.0,
                                       "indistinguishable_from_chosen": []}},
    }


def _case() -> Case:
    return Case(3, "single", [Truth("friction", plant={"friction_scale": 1.8})], 1)


def test_an_unexplained_verdict_is_printed_as_unexplained():
    """Before: the record's `finding` was the closest fit's line, "friction x1.79 ...",
    under a verdict scored "unexplained" (right family: NO)."""
    rec = score(_case(), _js("unexplained"), {"friction": {"current_a": 5.0}},
                {"current_a": 5.0}, 1.0, sizes=lambda t: None)
    assert rec["verdict_families"] == "unexplained"
    assert rec["top1"] is False
    assert rec["finding"].startswith("unexplained (closest: friction x1.79")
    assert "held-out shrink 31 % < 50 %" in rec["finding"]


def test_a_verdict_keeps_its_finding_line():
    rec = score(_case(), _js("friction_levels"), {"friction": {"current_a": 5.0}},
                {"current_a": 5.0}, 1.0, sizes=lambda t: None)
    assert rec["finding"] == "friction x1.79 [1.68, 1.92] (Coulomb and static levels)"
    assert rec["top1"] is True
