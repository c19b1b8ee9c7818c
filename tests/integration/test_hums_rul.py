"""RUL prediction on synthetic index curves with known answers, and the metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.hums import campaign as C
from bench.hums import fusion as F
from bench.hums import metrics as MX
from bench.hums import records as REC
from bench.hums import rul as R
from plant_rt.params import PlantParams


def _cubic_ci(t: np.ndarray) -> np.ndarray:
    """Ci flat at 1 until 60 s, then falling as a cubic: reaches 0.56 at exactly 110 s."""
    x = np.clip(t - 60.0, 0.0, None)
    return 1.0 - 0.44 * (x / 50.0) ** 3


def test_thesis_cubic_recovers_a_cubic_failure_time():
    t = np.arange(0.5, 120.01, 0.5)
    res = R.thesis_predict(t, _cubic_ci(t))
    assert res is not None and res.prediction is not None
    # threshold 0.93 and warning 0.80 crossings of the known curve (period ends)
    t_thr = 60 + 50 * (0.07 / 0.44) ** (1 / 3)
    t_warn = 60 + 50 * (0.20 / 0.44) ** (1 / 3)
    assert res.t_threshold_s == pytest.approx(t_thr, abs=0.5)
    assert res.t_warning_s == pytest.approx(t_warn, abs=0.5)
    assert res.point_toe_s == pytest.approx(110.0, abs=0.05)
    assert res.rul_s == pytest.approx(110.0 - res.t_warning_s, abs=0.1)
    lo, hi = res.prediction.band()
    assert lo <= 110.0 + 0.05 and hi >= 110.0 - 0.05


def test_thesis_with_noise_has_a_band_that_holds_the_answer():
    rng = np.random.default_rng(1)
    t = np.arange(0.5, 120.01, 0.5)
    ci = _cubic_ci(t) + 0.004 * rng.standard_normal(len(t))
    res = R.thesis_predict(t, ci, seed=4)
    lo, hi = res.prediction.band()
    assert hi - lo > 0.1
    assert lo - 1.0 <= 110.0 <= hi + 1.0


def test_no_prediction_without_a_warning():
    t = np.arange(0.5, 60.01, 0.5)
    assert R.thesis_predict(t, np.ones_like(t)) is None
    partial = R.thesis_predict(t, np.where(t > 30, 0.9, 1.0))
    assert partial is not None and partial.prediction is None
    assert math.isnan(partial.rul_s)


def _cal(**kw) -> F.Calibration:
    b = [10.0 * k for k in range(11)]
    curves = {f: [0.01 * x for x in b] for f in F.FEATURES}
    curves["lost_motion"] = [1.4 * x for x in b]
    base = dict(backlash_um=b, curves=curves, ci_curve=[1 - 0.0046 * x for x in b],
                sigma_um={"lost_motion": 0.1}, offset_um={}, weights={"lost_motion": 100.0},
                warn_um=1.0, floor_um=0.5, fail_um=90.0, lm_model=[])
    base.update(kw)
    return F.Calibration(**base)


def test_fused_exponential_recovers_a_known_failure_time():
    """b(t) = 0.01 (e^(0.08 t) - 1) um reaches b_fail = 90 um at ln(9001)/0.08 s."""
    t = np.arange(0.5, 130.0, 0.5)
    b_true = 0.01 * np.expm1(0.08 * t)
    t_fail = math.log(90.0 / 0.01 + 1) / 0.08
    rng = np.random.default_rng(0)
    lm = 1.4 * b_true + 1.4 * 0.1 * rng.standard_normal(len(t))
    table = {"lost_motion_m": lm * 1e-6}
    fr = F.FusedPredictor(_cal(), seed=3).run(t, table)
    assert fr.t_warning_s == pytest.approx(math.log(100 + 1) / 0.08, abs=3.0)
    late = [p for p in fr.predictions if p.t_pred_s >= 0.7 * t_fail]
    assert late
    for p in late[:20]:
        lo, hi = p.band()
        assert lo <= t_fail <= hi
        assert abs(p.toe_s - t_fail) < 0.2 * (t_fail - p.t_pred_s) + 0.5


def test_fusion_uses_what_the_log_has():
    cal = _cal(weights={"lost_motion": 100.0, "ci_harmonic": 1.0},
               sigma_um={"lost_motion": 0.1, "ci_harmonic": 1.0})
    n = 5
    table = {"lost_motion_m": np.full(n, np.nan), "ci_harmonic": np.full(n, 1 - 0.2)}
    # no encoder angle in this log: lost motion is NaN, Ci carries the estimate (0.2 -> 20)
    np.testing.assert_allclose(F.fused_backlash(table, cal), 20.0)
    table["lost_motion_m"] = np.full(n, 14e-6)     # 10 um
    got = F.fused_backlash(table, cal)
    np.testing.assert_allclose(got, (100 * 10 + 1 * 20) / 101)


def test_metrics_of_a_perfect_and_of_a_useless_predictor():
    t_f = 100.0
    perfect = [R.Prediction(tp, np.full(50, t_f)) for tp in np.arange(30.0, 100.0, 0.5)]
    s = MX.score_run(perfect, 30.0, t_f)
    assert s["ph_s"] == pytest.approx(70.0) and s["ph_life_frac"] == pytest.approx(0.7)
    assert s["alpha_lambda_0.5"] and s["alpha_lambda_0.9"]
    assert s["ra_0.5"] == pytest.approx(1.0)
    late = [R.Prediction(tp, np.full(50, t_f + 0.5 * (t_f - tp) + 5))
            for tp in np.arange(30.0, 100.0, 0.5)]
    s = MX.score_run(late, 30.0, t_f)
    assert s["ph_s"] == 0.0 and not s["alpha_lambda_0.5"]
    assert s["ra_0.5"] < 0.6
    # a predictor that only starts after lambda cannot meet alpha-lambda there
    s = MX.score_run(perfect[-10:], 95.0, t_f)
    assert not s["alpha_lambda_0.5"] and s["alpha_lambda_0.9"] is False


def test_true_failure_time_and_campaign_parameters():
    t = np.arange(0.5, 10.01, 0.5)
    assert REC.true_failure_time(t, np.linspace(1, 0.5, len(t))) == pytest.approx(
        t[np.flatnonzero(np.linspace(1, 0.5, len(t)) < 0.56)[0]])
    assert math.isnan(REC.true_failure_time(t, np.ones_like(t)))
    p = C.campaign_params(PlantParams(), np.random.default_rng(0), 7)
    assert p.schedule.kind == "rul" and p.sensors.noise and p.sensors.noise_seed == 7
    for name, (lo, hi) in C.CAMPAIGN_RANGES.items():
        assert lo <= p.get(name) <= hi


def test_scoring_leaves_matplotlib_settings_alone():
    """progpy rewrites matplotlib's rcParams when imported; scoring must not leak that
    into the figures drawn afterwards (fresh process: progpy imported for the first time)."""
    import subprocess
    import sys
    code = ("import matplotlib as mpl, numpy as np\n"
            "before = dict(mpl.rcParams)\n"
            "from bench.hums import metrics as MX\n"
            "from bench.hums import rul as R\n"
            "MX.score_run([R.Prediction(50.0, np.full(10, 100.0))], 50.0, 100.0)\n"
            "import progpy\n"
            "print(sorted(k for k in before if before[k] != mpl.rcParams[k]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
