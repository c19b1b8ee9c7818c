"""A baseline's thresholds are read and written only when every one is a finite number
>= 0 and each load has one above 0 (`baseline.threshold_problem`): a score is judged by
its ratio to its threshold, so a NaN, an infinite or a negative one judged every cycle
healthy. A feature without a threshold is absent from its load's table, which is not
damage. Thresholds that
overflow (an alpha far below what the held-out scores can bound) are refused where they
are set (`population.thresholds`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from bench import BenchError
from bench.rig import baseline as B
from bench.rig import population as P
from bench.rig.cycles import read_cycles

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "cranfield_sample"


def _file(thresholds: dict, anchor: dict | None = None) -> dict:
    """The smallest baseline JSON `from_json` reads: no load, only thresholds."""
    store = {"anchor": anchor} if anchor is not None else {}
    return {"format": B.FORMAT, "sources": ["t.csv"], "thresholds": thresholds,
            "lead_mm": 5.0, "load_unit": "kgf", "store": store, "loads": []}


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, -1.0, "7", None, True])
def test_a_threshold_that_is_not_a_finite_number_of_0_or_more_is_refused(value):
    d = _file({"40": {"thresholds": {"level": 1.5, "periodic": value}}})
    with pytest.raises(BenchError, match=r"^base\.json: damaged baseline: load 40, "
                                         r"feature periodic: threshold .* is not a finite "
                                         r"number >= 0$"):
        B.Baseline.from_json(d, "base.json")


def test_a_threshold_of_0_is_a_feature_left_out_but_a_load_needs_one_above():
    """`population.threshold_of` gives 0 where the healthy scores bound nothing above it,
    and `features.assess` leaves such a feature out; a load with only 0s flags nothing."""
    base = B.Baseline.from_json(_file({"40": {"thresholds": {"level": 1.5, "turn": 0.0}}}),
                                "base.json")
    assert base.thresholds["40"]["thresholds"]["turn"] == 0.0
    with pytest.raises(BenchError, match=r"load 40: no threshold above 0"):
        B.Baseline.from_json(_file({"40": {"thresholds": {"level": 0.0}}}), "base.json")


@pytest.mark.parametrize("table", [[], {"40": None}, {"40": {"thresholds": {}}},
                                   {"40": {"runs": [1, 2]}}])
def test_a_load_without_a_table_of_thresholds_is_refused(table):
    with pytest.raises(BenchError, match=r"^base\.json: damaged baseline"):
        B.Baseline.from_json(_file(table), "base.json")


def test_the_first_runs_thresholds_are_checked_too():
    d = _file({"40": {"thresholds": {"level": 1.5}}},
              anchor={"40": {"runs": [1, 2], "thresholds": {"level": math.nan}}})
    with pytest.raises(BenchError, match=r"load 40, feature level: the first runs' "
                                         r"\(--update anchor\) threshold nan"):
        B.Baseline.from_json(d, "base.json")


def test_good_thresholds_and_a_missing_feature_are_read():
    base = B.Baseline.from_json(_file({"40": {"thresholds": {"level": 1.5, "index": 8}}}),
                                "base.json")
    assert base.thresholds["40"]["thresholds"] == {"level": 1.5, "index": 8}
    assert B.Baseline.from_json(_file({}), "base.json").thresholds == {}


def test_a_non_finite_threshold_is_never_written(tmp_path):
    base = B.Baseline({}, ["t.csv"], thresholds={"40": {"thresholds": {"level": math.inf}}})
    out = tmp_path / "b.json"
    with pytest.raises(BenchError, match=r"b\.json: not written: load 40, feature level"):
        base.save(out)
    assert not out.exists()
    base.thresholds["40"]["thresholds"]["level"] = 1.5
    assert json.loads(base.save(out).read_text())["thresholds"]["40"]["thresholds"] == {
        "level": 1.5}


def test_thresholds_that_overflow_are_refused_where_they_are_set():
    cal = [c for c in read_cycles(SAMPLE / "normal_load40_runs1-4.csv.xz") if c.run in (1, 2)]
    with pytest.raises(BenchError, match=r"^load 40: the \w+ threshold at alpha 1e-300 is "
                                         r"inf, not a finite number"):
        P.calibrate(cal, 1e-300, lead_mm=5.0)
    thr = P.calibrate(cal, 1e-6, lead_mm=5.0).thresholds
    assert thr and all(math.isfinite(v) and v > 0 for v in thr.values())
