"""The one verdict model (`bench.core.verdict`): the levels and their one numeric code, the
stored forms `Level.parse` reads, the JSON shape, and the producers that return it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bench.core.verdict import Level, Verdict


def test_one_numeric_encoding():
    assert [(lv.name, int(lv)) for lv in sorted(Level)] == [
        ("UNKNOWN", -1), ("HEALTHY", 0), ("DEGRADED", 1), ("WARNING", 2), ("FAILURE", 3)]
    assert Level.HEALTHY < Level.DEGRADED < Level.WARNING < Level.FAILURE
    assert f"{Level.WARNING:9s}|" == "WARNING  |" and str(Level.FAILURE) == "FAILURE"


@pytest.mark.parametrize("stored, level", [
    ("HEALTHY", Level.HEALTHY), ("degraded", Level.DEGRADED), (" WARNING ", Level.WARNING),
    (3, Level.FAILURE), (np.int64(1), Level.DEGRADED), (2.0, Level.WARNING), ("0", Level.HEALTHY),
    (-1, Level.UNKNOWN), ("-1", Level.UNKNOWN), (None, Level.UNKNOWN), ("", Level.UNKNOWN),
    (math.nan, Level.UNKNOWN), (4, Level.UNKNOWN), (Level.WARNING, Level.WARNING)])
def test_parse_reads_every_stored_form(stored, level):
    """Names (any case), codes, and the forms UNKNOWN was stored in: the fleet store's
    NULL level, the live watcher's index 4."""
    assert Level.parse(stored) is level


@pytest.mark.parametrize("bad", ["FLAGGED", "ok", 5, -2, 1.5, True, [1]])
def test_parse_refuses_what_is_no_level(bad):
    with pytest.raises(ValueError, match="not a verdict level"):
        Level.parse(bad)


def test_verdict_is_frozen_and_has_one_json_shape():
    v = Verdict("DEGRADED", "Ci", ["Ci = 0.900 is below the threshold 0.93"], "thesis model")
    assert v.level is Level.DEGRADED and v.reasons == ("Ci = 0.900 is below the threshold 0.93",)
    assert v.flagged and v.judged
    with pytest.raises(dataclasses.FrozenInstanceError):
        v.level = Level.HEALTHY  # type: ignore[misc]
    js = v.to_json()
    assert js == {"level": "DEGRADED", "code": 1, "effect": "Ci",
                  "reasons": ["Ci = 0.900 is below the threshold 0.93"],
                  "reference": "thesis model"}
    assert Verdict.from_json(js) == v
    u = Verdict.unknown(["no current_a"], "rig baseline b.json")
    assert u.to_json()["code"] == -1 and not u.judged and not u.flagged
    assert u.effect == "not judged" and set(u.to_json()) == set(js)


def test_the_rig_verdict_is_the_one_verdict_with_its_cycle():
    from bench.rig.verdict import RigVerdict
    v = RigVerdict(level=Level.DEGRADED, effect="periodic", reasons=("periodic 9 vs 3",),
                   reference="baseline b.json, load 40 kgf", cycle="run 3 cycle 2",
                   fault="spall")
    assert isinstance(v, Verdict) and v.flagged and v.baseline == v.reference
    d = v.to_dict()
    assert d["level"] == "DEGRADED" and d["baseline"] == "baseline b.json, load 40 kgf"
    assert set(v.to_json()) == {"level", "code", "effect", "reasons", "reference"}


def test_the_rig_log_verdicts_of_report_and_gap_are_one_function():
    """`bench hums report` and `bench gap` give a rig log its verdict with
    `rig.verdict.baseline_verdict` / `model_verdict`: DEGRADED when a cycle or signal is
    outside, HEALTHY within, UNKNOWN when a signal it rests on is missing."""
    from bench.rig.verdict import baseline_verdict, model_verdict
    res = {"judged": True, "flagged": 1, "judged_cycles": 2, "effects": {"periodic": 1},
           "verdicts": [{"cycle": "c1", "verdict": "ok", "flagged": False, "judged": True},
                        {"cycle": "c2", "verdict": "spall-like", "flagged": True,
                         "judged": True}]}
    v = baseline_verdict(res, "baseline b.json")
    assert v is not None and (v.name, v.effect, v.reference) == (
        "DEGRADED", "periodic", "baseline b.json")
    assert v.reasons == ("1 of 2 cycle(s) outside the healthy baseline's thresholds",
                         "c2: spall-like")
    assert baseline_verdict({**res, "judged": False}, "b") is None
    m = {"rms_ratio": {"position_m": 1.2}, "threshold": {"position_m": 2.0},
         "significant": False, "not_judged": {}}
    assert model_verdict(m, "cal.json").name == "HEALTHY"
    m2 = {**m, "rms_ratio": {"position_m": 3.0}, "significant": True}
    assert (model_verdict(m2, "cal.json").name, model_verdict(m2, "c").effect) == (
        "DEGRADED", "position_m")
    assert model_verdict(m2, "c", effect="backlash").effect == "backlash"
    u = model_verdict({**m, "not_judged": {"current_a": "the log has no current_a"}}, "c")
    assert u.level is Level.UNKNOWN and "not judged: current_a" in u.reasons[-1]
