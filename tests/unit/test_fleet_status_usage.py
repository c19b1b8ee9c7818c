"""`bench fleet status`'s usage column says it sums the logged runs, and an actuator at
WARNING or FAILURE with ~0 % of L10 gets a note saying why (a synthetic fleet's unloaded
ground tests and its time compression), instead of a bare "1.14e-15 % of L10"."""

from __future__ import annotations

import math

from bench.fleet.status import ActuatorStatus, format_table


def _st(ident: str, verdict: str, life: float) -> ActuatorStatus:
    return ActuatorStatus(ident, 30, 1.7e9, verdict, 0.55, -0.01, life_consumed=life)


def test_near_zero_usage_beside_failure_is_explained():
    text = format_table([_st("EMA-0003", "FAILURE", 1.14e-17), _st("EMA-0001", "HEALTHY",
                                                                   2e-17)])
    lines = text.splitlines()
    assert "1.14e-15 % of L10 in the logged runs" in lines[1]
    note = " ".join(lines[3:])
    assert note.startswith("note: EMA-0003: WARNING or FAILURE with ~0 % of L10 used")
    assert "EMA-0001" not in note
    assert "time compression" in note and "flights that are not logged" in note


def test_no_note_where_the_usage_is_real_or_absent():
    rows = [_st("A", "FAILURE", 0.4), _st("B", "WARNING", math.nan), _st("C", "HEALTHY", 0.0)]
    text = format_table(rows)
    assert "note:" not in text and len(text.splitlines()) == 4
    assert "40 % of L10 in the logged runs" in text and "n/a (no run with a load" in text
