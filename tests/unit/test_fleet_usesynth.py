"""The use-driven synthetic fleet (`bench.fleet.synth`, wear="use"), the status as of a
date (`bench.fleet.status`) and the RUL check against the truth (`bench.fleet.truthcheck`).
The flight's life table is a fixed stand-in here (the simulated one is checked in
tests/integration/test_fleet_usesynth_flight.py), so nothing is simulated."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from bench import BenchError
from bench.fleet import synth as S
from bench.fleet.status import parse_as_of, status_of_series
from bench.fleet.truthcheck import check

TABLE = {0.5: 4e-9, 1.0: 1e-8, 1.5: 2.7e-8, 2.0: 6e-8}


@pytest.fixture
def table(monkeypatch):
    monkeypatch.setattr(S, "_LIFE_TABLE", dict(TABLE))
    monkeypatch.setattr(S, "SEVERITY_GRID", tuple(TABLE))
    return TABLE


def test_life_per_flight_interpolates_the_table_and_rises_with_severity(table):
    sev = np.array([0.5, 0.75, 1.0, 1.2, 2.0, 3.0])
    life = S.life_per_flight(sev, table)
    assert life[0] == pytest.approx(4e-9) and life[2] == pytest.approx(1e-8)
    assert np.all(np.diff(life) >= 0) and life[-1] == pytest.approx(6e-8)   # clamped


def test_wear_is_monotone_in_consumption_and_ends_at_s_1(table):
    util = {"flights_per_day": 5.0, "severity": 1.0}
    k = S.compression(30, table)
    fl, sev, cons, s = S.use_days(util, 1.0, 30, k, table, np.random.default_rng(3))
    cum = np.concatenate([[0.0], np.cumsum(cons)[:-1]])
    assert np.allclose(s, np.minimum(k * cum, 1.0))            # s_d = K sum_(j<d) c_j / B
    assert s[0] == 0.0 and np.all(np.diff(s) >= 0)
    # nominal use and budget 1: the end of life near NOMINAL_LIFE_FRAC x 30 = 45 days
    # (Poisson flights and the daily severity factor scatter it by ~10 %)
    assert s[-1] == pytest.approx(29 / 45, rel=0.25)
    act = S.Actuator("A", math.inf, {"schedule.backlash_growth": 10.0,
                                     "schedule.friction_growth": 2.0,
                                     "schedule.preload_start_n": 2000.0,
                                     "schedule.preload_zero_frac": 0.5}, 7.0, s=tuple(s))
    back = [S.wear_at(act, d)["effects.backlash_m"] for d in range(30)]
    assert np.all(np.diff(back) >= 0) and back[-1] > back[0]


def test_more_use_wears_faster(table):
    k = S.compression(20, table)
    out = {}
    for name, util in {"light": {"flights_per_day": 2.0, "severity": 0.7},
                       "heavy": {"flights_per_day": 8.0, "severity": 1.4}}.items():
        out[name] = S.use_days(util, 1.0, 20, k, table, np.random.default_rng(1))
    assert out["heavy"][2].sum() > 5 * out["light"][2].sum()
    assert out["heavy"][3][-1] > 3 * out["light"][3][-1]


def test_fleet_draws_are_deterministic_and_the_truth_holds_each_day(table):
    a, b = S.draw_fleet(4, 12, seed=7), S.draw_fleet(4, 12, seed=7)
    assert a == b and a != S.draw_fleet(4, 12, seed=8)
    assert len({x.utilisation["flights_per_day"] for x in a}) == 4
    truth = S.truth_of(a, 4, 12, 7, "use")
    row = truth["fleet"][0]
    assert len(row["life_consumed"]) == len(row["s"]) == len(row["flights"]) == 12
    assert row["life_consumed"][0] == pytest.approx(
        row["flights"][0] * float(S.life_per_flight(np.array([row["severity"][0]]), table)[0]))
    assert truth["use"]["compression"] == pytest.approx(S.compression(12, table))
    assert "not a thesis result" in truth["use"]["mapping"]
    # the time rule keeps its old draws: the same schedule and hour per actuator
    t = S.draw_fleet(4, 12, seed=7, wear="time")
    assert [x.schedule for x in t] == [x.schedule for x in a] and not t[0].s
    with pytest.raises(BenchError):
        S.draw_fleet(1, 1, 0, wear="calendar")


def _series(ci_by_actuator: dict[str, list[float]], epoch: float) -> dict[str, np.ndarray]:
    ids, t, ci = [], [], []
    for ident, values in ci_by_actuator.items():
        for d, c in enumerate(values):
            ids.append(ident)
            t.append(epoch + d * 86400.0 + 7 * 3600.0)
            ci.append(c)
    n = len(ids)
    verdict = ["FAILURE" if c < 0.56 else "WARNING" if c < 0.8 else "HEALTHY" for c in ci]
    return {"actuator_id": np.array(ids, dtype=object), "run_time": np.array(t),
            "ci": np.array(ci), "ci_harmonic": np.array(ci), "verdict": np.array(
                verdict, dtype=object), "life_consumed": np.full(n, np.nan),
            "reasons": np.array([""] * n, dtype=object)}


def test_status_as_of_ignores_later_tests():
    epoch = S.EPOCH.timestamp()
    s = _series({"A": [1.0, 1.0, 0.7, 0.5], "B": [1.0, 0.99]}, epoch)
    now = {st.ident: st for st in status_of_series(s)}
    assert now["A"].tests == 4 and now["A"].verdict == "FAILURE"
    then = {st.ident: st for st in status_of_series(s, as_of=parse_as_of("2026-01-06"))}
    assert then["A"].tests == 2 and then["A"].verdict == "HEALTHY"
    assert then["A"].last_time_s == epoch + 86400.0 + 7 * 3600.0 and then["B"].tests == 2
    assert status_of_series(s, as_of=epoch - 1.0) == []
    assert parse_as_of("2026-01-06T07:00:00") == dt.datetime(
        2026, 1, 6, 7, tzinfo=dt.UTC).timestamp()
    with pytest.raises(BenchError, match="--as-of"):
        parse_as_of("yesterday")


def test_truth_check_counts_detections_and_false_alarms():
    epoch = S.EPOCH.timestamp()
    days = 30
    a = [1.0] * 20 + [0.7, 0.5] + [0.5] * 8          # end of life on day 21
    b = [1.0] * 5 + [0.75] + [1.0] * 24                # a WARNING 25 days from any end
    truth = {"days": days, "epoch": S.EPOCH.isoformat(), "seed": 0, "wear": "use",
             "fleet": [{"actuator": "A", "s": [min(d / 21, 1.0) for d in range(days)]},
                       {"actuator": "B", "s": [0.0] * days}]}
    res = check(_series({"A": a, "B": b}, epoch), truth)
    assert res["end_of_life_in_window"] == 1 and res["with_rul_before_eol"] == 0
    assert res["flagged_on_eol_day"] == 1 and res["notice_days"] == [1.0]
    assert res["false_alarms"] == 1 and res["false_alarm_list"][0]["actuator"] == "B"
    assert res["alpha_lambda_hits"] == 0
