"""A 3-actuator mini usage campaign (bench.hums.prognosis_campaign): flights with
Archard wear to failure, daily ground tests, calibration on distinct seeds, prognosis
scored with progpy; and the CLI's one-line errors."""

from __future__ import annotations

import math

import pytest

from bench.cli import main
from bench.hums import prognosis_campaign as PC


def test_mini_campaign_runs_to_failure_and_scores_every_method(tmp_path):
    # heavy time compression (actuators fail within a few days) to stay cheap
    res = PC.run_usage_campaign(n=3, n_cal=2, n_healthy=1, n_cal_healthy=1, seed=40,
                                workers=1, progress=False, max_days=8, healthy_days=3,
                                acceleration=400000.0, sweep_points=5, sweep_noisy=2,
                                cal_healthy_days=2, kp=189455.0)
    assert len(res.runs) == 3
    failed = [r for r in res.runs if not r.get("censored")]
    assert failed, "no actuator failed within 8 days"
    for r in failed:
        assert 0 < r["t_failure"] <= 8
        for m in PC.METHODS:
            assert 0.0 <= r[m]["ph_life_frac"] <= 1.0
            assert r[m]["band"], m          # daily RUL percentiles from day one
            lo, med, hi = r[m]["band"][0][1:]
            assert lo <= med <= hi
    cal = res.cal
    assert cal.seeds["actuators"] == [PC.CAL_SEED, PC.CAL_SEED + 1]
    assert not set(cal.seeds["actuators"]) & {40, 41, 42}
    assert cal.w_grid[0] == 0.0 and cal.w_grid[-1] > 1.0
    assert res.false_alarms["ground_tests"] == 4        # days 0-3 of the healthy one
    assert "usage + health" in PC.markdown(res)
    assert math.isfinite(res.summary["all"]["life_days_median"])
    # its trends CSV runs through the external-trends path, with the usage rows
    from bench.hums.prognosis_trends import prognose_trends
    est, skipped = prognose_trends(PC.write_trends(res, tmp_path / "t.csv"), res.cal)
    assert set(est) == {"A40", "A41", "A42"} and skipped == []
    for r in res.runs:
        assert len(est[f"A{r['seed']}"]) == r["days"]
    assert [p.name for p in PC.figure(res, tmp_path)] == ["usage_campaign.png"]


@pytest.mark.parametrize("argv, msg", [
    (["hums", "campaign", "--usage", "--runs", "0"], "--runs must be >= 1"),
    (["hums", "prognose", "--trends", "/nonexistent.csv", "--calibration",
      "/nonexistent.json"], "no prognosis calibration"),
])
def test_cli_errors_are_one_line(argv, msg, capsys):
    assert main(argv) != 0
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err
