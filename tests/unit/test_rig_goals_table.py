"""The study's goals table says "met" only when a goal holds: the naming goal for the
pool and for every fault family (the spall stages, most of the cycles, would hide a
family named wrong)."""

from __future__ import annotations

from bench.rig.report_goals import summary_blocks


def _named(rate: float, per_family: dict[str, float]) -> dict:
    return {"goals": {"named": {"flagged": 100, "rate": rate, "rate_95": [rate - 0.01, rate],
                                "per_family": {k: {"rate": v} for k, v in per_family.items()}}}}


def _row(sm: dict, goal: str) -> list[str]:
    (table,) = summary_blocks(sm)
    return next(r for r in table.rows if r[0].startswith(goal))


def _met(sm: dict) -> str:
    return _row(sm, "physics name")[-1]


def test_the_naming_goal_is_met_only_when_every_family_meets_it():
    assert _met(_named(0.86, {"backlash": 0.31, "friction": 0.67, "spall": 0.90})) == \
        "no (backlash, friction below)"
    assert _met(_named(0.86, {"backlash": 0.75, "friction": 0.8, "spall": 0.90})) == "yes"
    assert _met(_named(0.6, {"spall": 0.6})) == "no (spall below)"


def test_detection_below_the_goal_is_not_met():
    sm = {"goals": {"detected": {"judged": 10, "rate": 0.893, "rate_95": [0.888, 0.897]}}}
    assert _row(sm, "fault cycles detected")[-1] == "no"
