"""The trend's own prognosis (bench.hums.trend_prognosis, trend_model, trend_run): RUL
bands that hold the truth on synthetic endurance trends, estimates that depend only on
the tests up to their own, the peers, the notes, the path chosen, and the campaign's
calibrated path unchanged."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.hums.trend_io import Trend
from bench.hums.trend_prognosis import Settings, prognose
from bench.hums.trend_synth import endurance_trend, write_csv

sys.path.insert(0, str(Path(__file__).parent))
from test_prognosis import synthetic_calibration, write_trends  # noqa: E402


def _trend(st) -> Trend:
    return Trend(st.name, "rms", "A", st.t, st.y, np.arange(len(st.t)))


def _run(st, **kw):
    s = Settings(healthy="5", failure=f"{st.failure_level:.6g}", **kw)
    return prognose(_trend(st), s)


@pytest.mark.parametrize("shape, seed", [("linear", 3), ("exponential", 4),
                                         ("piecewise", 5)])
def test_the_band_holds_the_truth_on_most_days_after_the_warning(shape, seed):
    st = endurance_trend(shape, seed)
    r = _run(st)
    c = r.cols
    warned = np.flatnonzero(c["warning"] > 0)
    assert len(warned), "no warning"
    t_w = st.t[warned[0]]
    assert t_w >= st.onset and st.t_failure - t_w >= 14.0
    days = [k for k in range(len(st.t)) if t_w <= st.t[k] < st.t_failure]
    inside = [c["rul_p5"][k] <= st.t_failure - st.t[k] <= c["rul_p95"][k] for k in days]
    assert np.mean(inside) >= 0.7, np.mean(inside)


def test_no_warning_and_no_rul_on_a_healthy_trend():
    for seed in range(6):
        r = _run(endurance_trend("healthy", seed))
        assert not np.any(r.cols["warning"] > 0), seed
        assert np.all(np.isnan(r.cols["rul_p50"]))
        assert "no change from healthy detected" in r.notes


def test_each_estimate_depends_only_on_the_tests_up_to_its_own():
    """The hidden use: the command run as of each test day on the data up to that day."""
    st = endurance_trend("exponential", 11)
    full = _run(st)
    for k in (4, len(st.t) // 2, len(st.t) - 3):
        cut = st.__class__(st.name, st.shape, st.t[:k + 1], st.y[:k + 1], st.healthy_level,
                           st.t_failure, st.onset)
        part = _run(cut)
        a, b = full.estimate(k), part.estimate(k)
        assert a == b, k


def test_a_band_of_one_value_always_says_why():
    for shape in ("jam", "knee", "noisy"):
        for seed in range(3):
            r = _run(endurance_trend(shape, seed))
            c = r.cols
            for k in np.flatnonzero(np.isfinite(c["rul_p5"])):
                if c["rul_p95"][k] - c["rul_p5"][k] < 0.25:
                    assert r.notes_at.get(k), (shape, seed, k)


def test_without_a_threshold_a_detection_and_no_rul():
    st = endurance_trend("piecewise", 2)
    r = prognose(_trend(st), Settings(healthy="5"))
    assert "detected_t" in r.events and st.onset <= r.events["detected_t"] < st.t_failure
    assert np.all(np.isnan(r.cols["rul_p50"]))
    k = len(st.t) - 1
    assert any("a RUL needs one" in n for n in r.notes_at[k])


def test_a_falling_index_with_decreasing():
    st = endurance_trend("linear", 8)
    y = 2.0 * st.healthy_level - st.y                      # the mirror image: falls to 0
    tr = Trend("F", "ci", "", st.t, y, np.arange(len(y)))
    down = prognose(tr, Settings(healthy="5", failure="0", decreasing=True))
    up = prognose(_trend(st), Settings(healthy="5", failure=repr(st.failure_level)))
    k = len(y) // 2
    assert down.cols["rul_p50"][k] == pytest.approx(up.cols["rul_p50"][k], rel=1e-9)
    assert down.cols["level_p5"][k] <= down.cols["level_p50"][k] <= down.cols["level_p95"][k]
    assert down.cols["level_p50"][k] == pytest.approx(
        2.0 * st.healthy_level - up.cols["level_p50"][k], rel=1e-9)


def test_the_peers_on_an_exact_exponential():
    t = np.arange(40.0)
    y = 1.0 * np.exp(0.02 * t)
    y[:5] = [0.99, 1.01, 1.0, 0.995, 1.005]
    tr = Trend("E", "i", "", t, y, np.arange(40))
    r = prognose(tr, Settings(healthy="5", failure=str(math.exp(0.02 * 60))))
    k = 39
    assert r.cols["exp_cross_t"][k] == pytest.approx(60.0, abs=1.5)
    z = (y - np.mean(y[:5])) / np.std(y[:5], ddof=1)
    first = int(np.argmax((z > 3.0) & (np.arange(40) >= 5)))
    assert r.events["z_alarm_t"] == t[first]


def test_the_crossing_equals_progpys_simulate_to_threshold():
    from bench.hums import trend_model as M
    f = M.Fit(30.0, 0.0, np.zeros(1), np.zeros(1), np.ones(1), np.zeros((1, 3)),
              np.zeros((1, 3, 3)), 1.0, np.ones(1), 0.0, 1.0, 0.0)
    for g, a, b, c, tc in ((0.08, 0.0, 0.05, 0.2, 12.0), (0.0, 0.01, 0.1, 0.3, 5.0),
                           (-0.02, 0.0, 0.3, 0.3, 0.0)):
        ours = float(M._crossing(f, *(np.array([v]) for v in (a, b, c, tc, g)))[0])
        s = 30.0 - tc
        r_now = c * math.exp(g * s) / float(M.phi(np.array(g), np.array(s)))
        m = M.make_model(g=g, b_rate=b / 30.0)
        m.parameters["x0"] = {"u": a + b + c, "r": r_now}
        res = m.simulate_to_threshold(lambda t, x=None, m=m: m.InputContainer({}), dt=0.01,
                                      save_freq=1e9)
        # the model steps exactly; the event is seen at the first step past it
        assert 0.0 <= res.times[-1] - ours <= 0.0101, (g, ours, res.times[-1])


def test_json_keeps_the_calibrated_shape_and_adds_to_it(tmp_path, capsys):
    st = endurance_trend("exponential", 6)
    f = write_csv([st], tmp_path / "rig.csv")
    out = tmp_path / "e.json"
    assert main(["hums", "prognose", "--trends", str(f), "--failure", "2x", "--json",
                 str(out), "--figures", str(tmp_path / "fig"), "--truth",
                 "2024-06-01"]) == 0
    rows = json.loads(out.read_text())[st.name]
    assert len(rows) == len(st.t)
    for key in ("t", "warning", "rul_p5", "rul_p50", "rul_p95", "notes", "date",
                "healthy_level", "failure_level", "z_alarm", "exp_cross_t"):
        assert key in rows[-1], key
    assert rows[-1]["failure_level"] == pytest.approx(2 * rows[-1]["healthy_level"])
    text = capsys.readouterr().out
    assert "peers on the same tests" in text and "healthy reference: the first 5" in text
    assert len(list((tmp_path / "fig").glob("*.png"))) == 1


def test_the_trend_path_without_a_calibration_and_with_a_foreign_index(tmp_path, capsys,
                                                                       monkeypatch):
    """Before: no calibration was a refusal ("run bench hums campaign --usage first"), a
    calibration without the rig's index one too ("no index the calibration knows")."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    st = endurance_trend("piecewise", 9)
    f = write_csv([st], tmp_path / "rig.csv", index="motor_rms")
    assert main(["hums", "prognose", "--trends", str(f)]) == 0
    cap = capsys.readouterr()
    assert "no prognosis calibration" in cap.err and "a RUL needs one" in cap.out
    cf = tmp_path / "cal.json"
    cf.write_text(json.dumps(synthetic_calibration().to_json()))
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf)]) == 0
    cap = capsys.readouterr()
    assert "has no curve for motor_rms: the trend's own prognosis" in cap.err


GOLDEN_P50 = {"A-1": [29.919808183, 16.439495326, 17.207667353, 16.597587325],
              "B-2": [None, None, None, 47.51438326416754]}


def test_the_calibrated_path_keeps_its_numbers(tmp_path, capsys):
    """The campaign's path through the CLI gives what it gave before the trend's own path
    (numbers of the previous release on the same synthetic calibration and trends)."""
    cal = synthetic_calibration()
    cf = tmp_path / "cal.json"
    cf.write_text(json.dumps(cal.to_json()))
    f = tmp_path / "trends.csv"
    write_trends(f, cal, {"A-1": 1 / 20.0, "B-2": 1 / 40.0})
    out = tmp_path / "e.json"
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf), "--seed",
                 "1", "--json", str(out)]) == 0
    got = json.loads(out.read_text())
    assert [round(e["rul_p50"], 9) for e in got["A-1"][:4]] == GOLDEN_P50["A-1"]
    assert got["B-2"][3]["rul_p50"] == pytest.approx(GOLDEN_P50["B-2"][3], rel=1e-12)
    assert got["A-1"][-1]["rul_p95"] == pytest.approx(9.552603973149928, rel=1e-12)
    assert got["B-2"][-1]["w_p50"] == pytest.approx(0.27168918697096595, rel=1e-12)


def test_the_calibrated_path_says_when_a_value_is_outside_its_curves(tmp_path, capsys):
    cal = synthetic_calibration()
    cf = tmp_path / "cal.json"
    cf.write_text(json.dumps(cal.to_json()))
    f = tmp_path / "t.csv"
    f.write_text("time,actuator,index,value\n0,A,ci_harmonic,0.99\n1,A,ci_harmonic,0.98\n"
                 "2,A,ci_harmonic,0.2\n")
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf)]) == 0
    err = capsys.readouterr().err
    assert "1 value(s) of ci_harmonic outside the calibrated range" in err
    assert "actuator A at 2, 0.2" in err


def test_the_crossing_equals_a_brute_force_search():
    from bench.hums import trend_model as M
    rng = np.random.default_rng(0)
    n = 400
    f = M.Fit(100.0, 0.0, np.zeros(1), np.zeros(1), np.ones(1), np.zeros((1, 3)),
              np.zeros((1, 6)), 1.0, np.ones(1), 0.0, 1.0, 0.0)
    a, b = rng.normal(0, 0.05, n), rng.normal(0.1, 0.3, n)
    c = np.abs(rng.normal(0.2, 0.2, n))
    keep = a + b + c < 1
    a, b, c = a[keep], b[keep], c[keep]
    tc = rng.uniform(0, 97, len(a))
    g = rng.choice([0.0, 0.01, 0.03, 0.06, 0.2, -0.005, -0.01, -0.03], len(a))
    got = M._crossing(f, a, b, c, tc, g)
    tt = np.linspace(0, M.HORIZON * 100, 100001)
    for i in range(len(a)):
        u = M.level(f, a[i], b[i], c[i], tc[i], g[i], 100 + tt)
        k = int(np.argmax(u >= 1.0))
        ref = tt[k] if u[k] >= 1.0 else np.inf
        assert (np.isinf(ref) and np.isinf(got[i])) or abs(ref - got[i]) <= 0.06, i
    assert 0.05 < np.isinf(got).mean() < 0.5          # both kinds are in the sample



def test_the_table_prints_every_actuator_name_whole(capsys):
    """'exponential-7' was cut to 'exponential-' (a 12-character column), and the
    command prints its rows as they come, so the width is the longest name of all."""
    data = Path(__file__).parents[1] / "data" / "trends" / "endurance.csv"
    assert main(["hums", "prognose", "--trends", str(data), "--failure", "2x"]) == 0
    head, *rows = capsys.readouterr().out.splitlines()[:3]
    assert [r.split()[0] for r in rows] == ["exponential-7", "jam-8"]
    end = head.index("tests") + len("tests")      # right-aligned under its header
    assert all(r[:end].split()[-1].isdigit() and r[end] == " " for r in rows)


def test_a_healthy_reference_of_every_test_says_none_is_left_to_judge():
    st = endurance_trend("exponential", 11)
    r = prognose(Trend(st.name, "rms", "A", st.t, st.y, np.arange(len(st.t))),
                 Settings(healthy=str(len(st.t)), failure="2x"))
    assert any("none is left to judge" in n for n in r.notes)
    assert "no change from healthy detected" not in r.notes
