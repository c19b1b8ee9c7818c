"""The prognosis (bench.hums.prognosis, prognosis_trends): the particle filter recovers a
known wear coefficient, its closed-form failure times equal progpy's MonteCarlo predictor,
and a synthetic trends CSV gives the right RUL."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from bench import BenchError
from bench.hums.prognosis import PrognosisCalibration, WearPrognoser, index_wear
from bench.hums.prognosis_trends import prognose_trends, read_trends


def synthetic_calibration() -> PrognosisCalibration:
    """Curves shaped like the bench's: friction linear, lost motion from w = 0.1, Ci on
    15 harmonics falling; prior ln k = ln(1/30) +- 0.4 per unit exposure and per day."""
    g = [float(x) for x in np.linspace(0.0, 1.3, 14)]
    return PrognosisCalibration(
        w_grid=g,
        curves={"friction_current_a": [0.035 + 0.15 * w for w in g],
                "lost_motion_um": [max(0.0, w - 0.1) * 130.0 for w in g],
                "ci_harmonic": [1.0 - 0.44 * w for w in g]},
        sigma={"friction_current_a": 0.0045, "lost_motion_um": 0.5, "ci_harmonic": 0.005},
        lnk_mean=math.log(1 / 30), lnk_std=0.4, lnk_time_mean=math.log(1 / 30),
        lnk_time_std=0.4, exposure_rate_mean=1.0, lfs_std=0.05, warn_w=0.08)


def series(cal: PrognosisCalibration, k: float, days: int, seed: int = 1
           ) -> list[tuple[float, float, dict[str, float]]]:
    """(day, exposure since the last test, noisy indexes) with w = k x exposure."""
    rng = np.random.default_rng(seed)
    w, out, e_prev = 0.0, [], 0.0
    for d in range(days):
        w += k * e_prev
        obs = {n: float(cal.curve(n, np.array(w)) + rng.normal(0.0, cal.sigma[n]))
               for n in cal.curves}
        out.append((float(d), e_prev, obs))
        e_prev = float(rng.uniform(0.7, 1.3))
    return out


def test_particle_filter_recovers_a_known_wear_coefficient():
    cal = synthetic_calibration()
    k = 1 / 18.0                       # 1.7 sd faster than the prior's median
    pr = WearPrognoser(cal, n_particles=600, seed=3)
    for t, e, obs in series(cal, k, 10):
        est = pr.update(t, e, obs)
    assert math.exp(est.lnk_median) == pytest.approx(k, rel=0.08)
    w_true = k * sum(e for _, e, _ in series(cal, k, 10))
    assert est.w_pct["5"] < w_true < est.w_pct["95"]
    # the RUL band holds the true RUL (future exposure ~1 per day)
    rul_true = (1 - w_true) / k
    assert est.rul_pct["5"] < rul_true < est.rul_pct["95"]
    assert est.rul_pct["95"] - est.rul_pct["5"] < 0.5 * rul_true


def test_usage_alone_gives_the_prior_band_and_health_narrows_it():
    cal = synthetic_calibration()
    prior = WearPrognoser(cal, n_particles=600, seed=4)
    first = prior.update(0.0, 0.0, None)       # day one, before any ground test
    assert first.rul_pct["50"] == pytest.approx(30.0, rel=0.1)   # 1 / median k at rate 1
    health = WearPrognoser(cal, n_particles=600, seed=4)
    for t, e, obs in series(cal, 1 / 30.0, 8):
        prior.update(t, e, None) if t > 0 else None
        last = health.update(t, e, obs)
    width = prior.estimate().rul_pct["95"] - prior.estimate().rul_pct["5"]
    assert last.rul_pct["95"] - last.rul_pct["5"] < 0.5 * width


def test_closed_form_failure_times_equal_progpys_monte_carlo():
    import matplotlib
    with matplotlib.rc_context():
        from progpy.predictors import MonteCarlo
        from progpy.uncertain_data import UnweightedSamples
    cal = synthetic_calibration()
    pr = WearPrognoser(cal, n_particles=20, seed=5)
    for t, e, obs in series(cal, 1 / 25.0, 4):
        pr.update(t, e, obs)
    ours = np.sort(pr.toe_samples())
    p = pr.particles()
    rate = pr.future_rate()
    pr.model.apply_process_noise = lambda x, dt=1: x      # the prediction is noise-free
    x = UnweightedSamples([{"w": a, "lnk": b, "lfs": c} for a, b, c in
                           zip(p["w"], p["lnk"], p["lfs"], strict=True)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)   # progpy's own internals
        mc = MonteCarlo(pr.model).predict(
            x, lambda t, x=None: pr.model.InputContainer({"e": rate}), dt=0.01,
            horizon=200, t0=pr.t)
        theirs = np.sort([s["failure"] for s in mc.time_of_event])
    assert np.max(np.abs(theirs - ours)) < 0.02


def test_index_wear_and_warning_level():
    cal = synthetic_calibration()
    assert index_wear(cal, {"friction_current_a": 0.035, "ci_harmonic": 1.0}) < 0.02
    assert index_wear(cal, {"friction_current_a": 0.035 + 0.15 * 0.5,
                            "lost_motion_um": 52.0, "ci_harmonic": 0.78}) == pytest.approx(
                                0.5, abs=0.02)


def write_trends(path, cal, k_by_actuator, days=12):
    rows = ["time,actuator,index,value"]
    for a, k in k_by_actuator.items():
        for t, _, obs in series(cal, k, days, seed=len(rows)):
            for n, v in obs.items():
                rows.append(f"{t * 1.0 + 3.0},{a},{n},{v}")
        rows.append(f"3.0,{a},unknown_index,3")
    path.write_text("\n".join(rows) + "\n")


def test_trends_csv_gives_each_actuators_rul(tmp_path):
    cal = synthetic_calibration()
    f = tmp_path / "trends.csv"
    # time-only exposure: w = k t, so RUL at the last test (day 11) = 1/k - 11
    write_trends(f, cal, {"A-1": 1 / 20.0, "B-2": 1 / 40.0})
    res, skipped = prognose_trends(f, cal, seed=1)
    assert skipped == ["unknown_index"]
    assert set(res) == {"A-1", "B-2"}
    for a, k in (("A-1", 1 / 20.0), ("B-2", 1 / 40.0)):
        last = res[a][-1]
        true = 1 / k - 11.0
        assert last.rul_pct["50"] == pytest.approx(true, rel=0.2), a
        assert last.rul_pct["5"] < true < last.rul_pct["95"], a


def test_trends_csv_errors(tmp_path):
    f = tmp_path / "bad.csv"
    f.write_text("time,actuator,value\n1,a,2\n")
    with pytest.raises(BenchError, match="needs the columns"):
        read_trends(f)
    f.write_text("time,actuator,index,value\nx,a,ci,2\n")
    with pytest.raises(BenchError, match="neither a number nor an ISO date"):
        read_trends(f)
    f.write_text("time,actuator,index,value\n1,a,foo,2\n")
    with pytest.raises(BenchError, match="no index the calibration knows"):
        prognose_trends(f, synthetic_calibration())


@pytest.mark.parametrize("change, msg", [
    ({"w_grid": "x"}, "w_grid is not a list of at least 2 numbers"),
    ({"curves": 5}, "curves is not index name -> a list of numbers, one per w_grid point"),
    ({"curves": {"ci_harmonic": [1.0, 0.9]}}, "curves is not index name -> a list of"),
    ({"sigma": None}, "sigma is not index name -> a number"),
    ({"lnk_mean": "a"}, "lnk_mean is not a number"),
])
def test_a_calibration_of_the_wrong_shape_is_one_line(tmp_path, capsys, change, msg):
    """Found by fuzzing: a calibration JSON with the right keys and values
    of the wrong type reached the CLI's catch-all (TypeError, exit 1); a trends file
    that is not UTF-8 too (UnicodeDecodeError)."""
    import json

    from bench.cli import main
    cf = tmp_path / "cal.json"
    cf.write_text(json.dumps({**synthetic_calibration().to_json(), **change}))
    f = tmp_path / "trends.csv"
    write_trends(f, synthetic_calibration(), {"RIG-7": 1 / 25.0})
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {cf}: not a prognosis calibration: {msg}"), err
    assert "\n" not in err
    cf.write_text(json.dumps(synthetic_calibration().to_json()))
    f.write_bytes(b"\x91\xb6garbage")
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf)]) == 2
    assert capsys.readouterr().err.strip() == (f"error: {f}: not UTF-8 text (byte 0x91 at "
                                               "offset 0); a trends file must be UTF-8 text")


def test_bench_hums_prognose_on_a_trends_csv(tmp_path, capsys):
    import json

    from bench.cli import main
    cal = synthetic_calibration()
    cf = tmp_path / "cal.json"
    cf.write_text(json.dumps(cal.to_json()))
    f = tmp_path / "trends.csv"
    write_trends(f, cal, {"RIG-7": 1 / 25.0})
    out = tmp_path / "est.json"
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf),
                 "--json", str(out)]) == 0
    captured = capsys.readouterr()
    assert "RIG-7" in captured.out and "unknown_index" in captured.err
    rows = json.loads(out.read_text())["RIG-7"]
    assert len(rows) == 12
    assert rows[-1]["rul_p50"] == pytest.approx(25.0 - 11.0, rel=0.25)


def test_the_filter_is_deterministic_for_a_seed():
    cal = synthetic_calibration()
    runs = []
    for _ in range(2):
        np.random.seed(None)                    # the global state must not matter
        pr = WearPrognoser(cal, n_particles=300, seed=9)
        for t, e, obs in series(cal, 1 / 22.0, 6):
            est = pr.update(t, e, obs)
        runs.append(est.rul_pct)
    assert runs[0] == runs[1]
