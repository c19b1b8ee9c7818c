"""The trend prognosis's final check (bench.hums.trend_check): its seeds apart from every
seed the model was developed or scored on, and the truth each trend carries."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.hums import trend_check as TC

pytestmark = pytest.mark.unit


def test_the_final_check_seeds_are_apart_from_the_development_and_held_out_ones():
    seeds = {TC.FINAL_SEED + 100 * s + k for s in range(len(TC.SHAPES)) for k in range(100)}
    assert min(seeds) == 7300 and max(seeds) < 8000
    # development 100-139, held out 1000-1999 (eval_trend_prognosis), tests below 100
    assert not seeds & set(range(0, 2000))


@pytest.mark.parametrize("shape", [s for s in TC.SHAPES if s != "healthy-seasonal"])
def test_each_failing_trend_ends_at_its_truth_near_twice_its_healthy_level(shape):
    for k in range(3):
        tr = TC.final_trend(shape, k)
        assert math.isfinite(tr.t_failure) and tr.t[-1] <= tr.t_failure
        assert len(tr.t) >= 15 and np.all(np.diff(tr.t) > 0)
        assert tr.onset < tr.t_failure
        # the last tests lie near the failure level, the first near the healthy one
        assert np.median(tr.y[:5]) == pytest.approx(tr.healthy_level, rel=0.08)
        if tr.t_failure - tr.t[-1] < 5.0 and shape in ("power", "paris"):
            assert tr.y[-1] == pytest.approx(tr.failure_level, rel=0.15)


def test_the_healthy_seasonal_trend_never_fails_and_wanders_about_its_level():
    tr = TC.final_trend("healthy-seasonal", 0)
    assert math.isinf(tr.t_failure)
    assert abs(np.mean(tr.y) / tr.healthy_level - 1.0) < 0.05


@pytest.mark.parametrize("shape", ["gamma", "wiener"])
def test_a_random_path_that_fails_late_is_tested_up_to_its_failure(shape):
    """A path of a random process can fail after the life it was drawn for; its tests
    must still run to the failure (they once stopped at that life, weeks before)."""
    for k in range(20):
        tr = TC.final_trend(shape, k)
        assert tr.t_failure - tr.t[-1] < 8.0, (k, tr.t_failure, tr.t[-1])


def test_the_cli_writes_a_trend_the_prognosis_reads(tmp_path, capsys):
    from bench.hums.trend_io import read_table
    out = tmp_path / "p.csv"
    assert TC.main(["--law", "paris", "healthy-seasonal", "--trend", "0", "1",
                    "--out", str(out)]) == 0
    tab = read_table(out)
    assert [t.actuator for t in tab.trends] == ["paris-7400", "healthy-seasonal-7801"]
    text = capsys.readouterr().out
    assert "paris-7400" in text and "never reached" in text


def test_a_trend_number_beyond_its_law_is_refused(capsys):
    """Trend 100 of one law would be trend 0 of the next one's seeds."""
    with pytest.raises(ValueError, match="trends 0 to 99"):
        TC.final_trend("power", 100)
    with pytest.raises(SystemExit):
        TC.main(["--law", "power", "--trend", "100", "--out", "x.csv"])
    assert "trends 0 to 99" in capsys.readouterr().err


def test_an_output_that_cannot_be_written_is_one_line(tmp_path, capsys):
    from bench.hums import trend_synth as TS
    for main, args in ((TC.main, ["--law", "power", "--trend", "0"]),
                       (TS.main, ["--shape", "linear", "--seed", "1"])):
        with pytest.raises(SystemExit):
            main(args + ["--out", str(tmp_path)])          # a directory
        err = capsys.readouterr().err
        assert f"cannot write {tmp_path}: Is a directory" in err and "Traceback" not in err
