"""The HUMS figures (sweep, RUL run, campaign) are drawn with matplotlib's Figure API: they
are written without importing pyplot or choosing a backend for the caller (fresh process),
on synthetic results with known content."""

from __future__ import annotations

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

from bench.hums import campaign as C
from bench.hums import fusion as F
from bench.hums import monitor as M
from bench.hums import rul_run
from bench.hums import sweep as S
from bench.hums.records import RunRecord, true_failure_time
from bench.hums.rul import thesis_predict


def _cal() -> F.Calibration:
    b = [10.0 * k for k in range(11)]
    curves = {f: [0.01 * x for x in b] for f in F.FEATURES}
    curves["lost_motion"] = [1.4 * x for x in b]
    return F.Calibration(b, curves, [1 - 0.0046 * x for x in b], {"lost_motion": 0.1}, {},
                         {"lost_motion": 100.0}, 1.0, 0.5, 90.0)


def _rul_result() -> rul_run.RulResult:
    t = np.arange(0.5, 120.01, 0.5)
    ci = 1.0 - 0.44 * (np.clip(t - 60.0, 0.0, None) / 50.0) ** 3
    b_um = 0.01 * np.expm1(0.08 * t)
    truth = {"preload_n": np.maximum(0.0, 2000.0 * (1 - t / 60.0)), "backlash_m": b_um * 1e-6,
             "friction_scale": 1.0 + 3.0 * (t / 120.0) ** 2}
    table = {"ci": ci, "ci_harmonic": ci, "lost_motion_m": 1.4 * b_um * 1e-6}
    rec = RunRecord(t, table, truth, {"duration_s": 120.0})
    cal = _cal()
    th = thesis_predict(t, ci)
    fr = F.FusedPredictor(cal, seed=3).run(t, table)
    return rul_run.RulResult(True, rec, rec, true_failure_time(t, ci), th, th, fr, cal, 1.0,
                             0.0)


def _campaign_result(res: rul_run.RulResult) -> C.CampaignResult:
    per = {m: {"ph_life_frac": 0.4, "warning_life_frac": 0.5} for m in C.METHODS}
    fr = res.fused
    assert fr is not None
    ex = {"index": 0, "t_s": res.record.t_s.tolist(),
          "b_true_um": (res.record.truth["backlash_m"] * 1e6).tolist(),
          "b_fused_um": fr.b_um.tolist(), "t_failure_s": res.t_failure_s}
    return C.CampaignResult([C.RunScore(0, {}, res.t_failure_s, per)], {}, {}, _cal(), 0.0,
                            1, 0, "", ex)


def _sweep_result() -> S.SweepResult:
    fit = M.GainFit(20.0, 1.9e5, 1e-6, 1e-5, 3e-4, 1.9e5, 10, 5, True, ())
    t = np.arange(0.0, 2.0, 1e-3)
    sine = np.sin(2 * math.pi * 2.0 * t)
    fit_series = {k: (1e-3 * sine).tolist() for k in (
        "real_position_m", "start_position_m", "fitted_position_m")}
    fit_series.update(t_s=t.tolist(), real_current_a=sine.tolist(),
                      fitted_current_a=sine.tolist())
    points = []
    for g, name in S.MANEUVERS.items():
        for noise in (False, True):
            for d in S.SHOWN:
                ix = {"cp": 1 + 0.08 * d, "mean_error_m": 7e-5 * d, "ci": 1 - 0.46 * d,
                      "ci_harmonic": 1 - 0.4 * d, "peak_ratio": 1 + d}
                cur = (1 + 0.2 * d) * sine + 0.3 * d * np.sin(3 * 2 * math.pi * 2.0 * t)
                series = {"t_s": t.tolist(), "current_a": cur.tolist(),
                          "nominal_current_a": sine.tolist()}
                points.append(S.Point(g, name, noise, d, ix, 1 + 1.5 * d, 1.2, 1.0, series))
    return S.SweepResult(fit, fit_series, points, (False, True), list(S.SHOWN), 0.0)


def draw_all(out: str) -> list[str]:
    """Every HUMS figure of the synthetic results into `out` (called in a fresh process)."""
    res = _rul_result()
    paths = rul_run.figures(res, out) + C.campaign_figure(_campaign_result(res), out)
    paths += S.figures(_sweep_result(), out)
    return sorted(p.name for p in paths)


def test_figures_are_written_without_pyplot(tmp_path):
    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
            "import matplotlib\n"
            "from test_hums_figures import draw_all\n"
            f"print(draw_all({str(tmp_path)!r}))\n"
            "print('matplotlib.pyplot' in sys.modules)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=180)
    assert r.returncode == 0, r.stderr
    names, pyplot = r.stdout.strip().splitlines()
    assert names == str(sorted(["r1_ci_trend_noise.png", "r2_rul_noise.png", "campaign.png",
                                "h1_fit.png", "h2_cp_error.png", "h3_cp_error.png",
                                "h4_ci_ratio.png", "h5_spectrum.png"]))
    assert pyplot == "False"
    for name in ast.literal_eval(names):
        assert (tmp_path / name).stat().st_size > 10_000
