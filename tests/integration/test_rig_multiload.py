"""The baseline fallback judges each cycle of a log at its own load: a log
whose cycles run at several loads (no split key: each cycle's median logged load), a
cycle at a load the baseline lacks ("not judged: no baseline at load X", the rest run),
and the report's figure showing the most flagged cycle, saying which. Built from the
Cranfield sample (load 40 kgf): the baseline holds healthy runs 1-2 at 40 kgf and the
same cycles relabelled 20 kgf."""

from __future__ import annotations

import json

import numpy as np
import pytest
from sample_data import HEALTHY, SPALLING, import_cycles

from bench.cli import main
from bench.signals.trace import Trace

FIT = [f"load=40_run={r}_group={g}.parquet" for r, gs in ((1, (51, 52, 53)), (2, (56, 57, 58)))
       for g in gs]
KGF = 9.80665


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("multiload")
    import_cycles(HEALTHY, d / "n")
    import_cycles(SPALLING, d / "s")
    paths = []
    for f in FIT:                      # the healthy cycles at 40 kgf and again at 20 kgf
        tr = Trace.load(d / "n" / f)
        paths.append(d / "n" / f)
        tr.meta["split"] = {**tr.meta["split"], "load": 20}
        tr.save(d / "n" / f.replace("load=40", "load=20"))
        paths.append(d / "n" / f.replace("load=40", "load=20"))
    from bench.rig.fallback import build_from_logs
    base, _ = build_from_logs(paths, 5.0)
    base.save(d / "base.json")
    # one log, no split key, three cycles: healthy run 3 at 20 kgf, the spall at 40 kgf,
    # healthy run 4 at 30 kgf (not in the baseline); the load logged per sample in N
    parts = [(d / "n" / "load=40_run=3_group=61.parquet", 20.0),
             (d / "s" / "load=40_run=1_group=51.parquet", 40.0),
             (d / "n" / "load=40_run=4_group=66.parquet", 30.0)]
    cols: dict[str, list[np.ndarray]] = {}
    t0 = 0.0
    for path, kgf in parts:
        tr = Trace.load(path)
        t = np.asarray(tr["t_s"], float) - float(tr["t_s"][0]) + t0
        t0 = float(t[-1]) + tr.dt
        for k, v in {"t_s": t, "setpoint_position_m": tr["setpoint_position_m"],
                     "position_m": tr["position_m"], "current_a": tr["current_a"],
                     "load_force_n": np.full(len(t), kgf * KGF)}.items():
            cols.setdefault(k, []).append(np.asarray(v, float))
    Trace({k: np.concatenate(v) for k, v in cols.items()}, {"source": "three loads"}).save(
        d / "mixed.npz")
    return d


def test_each_cycle_at_its_own_load(data, capsys):
    assert main(["gap", str(data / "mixed.npz"), "--baseline", str(data / "base.json"),
                 "--json", str(data / "gap.json")]) == 0
    out = capsys.readouterr().out
    res = json.loads((data / "gap.json").read_text())
    v = res["verdicts"]
    assert [x["judged"] for x in v] == [True, True, False]
    assert [x["baseline_load"] for x in v[:2]] == [20.0, 40.0]
    assert not v[0]["flagged"] and v[1]["flagged"] and v[1]["effect"] == "periodic"
    assert "load 20 kgf" in v[0]["baseline"] and "load 40 kgf" in v[1]["baseline"]
    assert v[2]["verdict"] == "not judged: no baseline at load 294 N (= 29.98 kgf)"
    assert "load 294 run 0 cycle 3" in v[2]["cycle"]
    assert res["cycles"] == 3 and res["judged_cycles"] == 2 and res["flagged"] == 1
    assert res["loads"] == {"20": 1, "40": 1} and res["worst"] == 1
    assert "[baseline load 20]" in out and "[baseline load 40]" in out
    assert "verdict: 1 / 2 cycle(s) flagged (periodic 1), 1 not judged" in out
    assert "load 20 kgf" in out.splitlines()[1] and "load 40 kgf" in out.splitlines()[1]


def test_the_report_figure_shows_the_most_flagged_cycle(data, tmp_path):
    assert main(["hums", "report", str(data / "mixed.npz"), "--baseline",
                 str(data / "base.json"), "--out", str(tmp_path)]) == 0
    page = (tmp_path / "report.html").read_text()
    assert "The most flagged cycle against the healthy baseline" in page
    assert "cycle 2: the most flagged of 2 cycles judged" in page
    assert "not judged: no baseline at load 294 N" in page


def test_gap_report_against_the_baseline(data, tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["gap", str(data / "mixed.npz"), "--baseline", str(data / "base.json"),
                 "--report", str(out)]) == 0
    assert f"report: {out / 'index.html'}" in capsys.readouterr().out
    page = (out / "index.html").read_text()
    assert "<h1>Sim-to-real gap: mixed.npz</h1>" in page
    assert "DEGRADED" in page and "given with --baseline" in page
    assert "cycle 2: the most flagged of 2 cycles judged" in page
    assert page.count("data:image/png;base64,") == 2          # signals, baseline figure
    js = json.loads((out / "indexes.json").read_text())[0]
    assert js["baseline"]["flagged"] == 1 and js["verdict"] == "DEGRADED"


def test_gap_report_against_the_calibrated_model(data, tmp_path, capsys):
    cal = tmp_path / "cal.json"
    assert main(["calibrate", *[str(data / "n" / f) for f in FIT[:3]], "--actuator",
                 "cranfield", "-o", str(cal)]) == 0
    out = tmp_path / "rep"
    assert main(["gap", str(data / "s" / "load=40_run=1_group=51.parquet"), "--nominal",
                 str(cal), "--against", "model", "--report", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"report: {out / 'index.html'}" in text
    page = (out / "index.html").read_text()
    verdict = text.split("verdict: ")[-1].split(" (baseline")[0]
    assert f"Gap against the calibrated model: {verdict}" in page
    for effect in ("friction", "force_gain", "localised_resistance"):
        assert f"<td>{effect}: " in page            # the ranking
    assert page.count("data:image/png;base64,") == 2          # signals, gap by position
    js = json.loads((out / "indexes.json").read_text())[0]
    assert js["gap"]["verdict"] == verdict and js["model"] is not None


def test_one_verdict_for_one_cycle_wherever_it_is_read(data):
    """`bench gap` / `bench hums report` (fallback.assess) and `bench rig assess` / the
    study (features.rig_verdict) give one cycle the same verdict: level, signature, fault
    family, text, provisional."""
    from bench.rig.baseline import Baseline
    from bench.rig.cycles import cycles_from_trace
    from bench.rig.fallback import assess
    from bench.rig.features import cycle_features, rig_verdict
    base = Baseline.load(data / "base.json")
    path = data / "s" / "load=40_run=1_group=51.parquet"
    tr = Trace.load(path)
    gap = assess(base, tr, path.name)["verdicts"][0]
    c = cycles_from_trace(tr, path.name)[0]
    thr = base.thresholds["40"]["thresholds"]
    own = rig_verdict(base, cycle_features(base.for_load(40.0), c, base.lead_mm), thr)
    assert own.flagged
    for k in ("level", "effect", "fault", "verdict", "provisional", "flagged"):
        assert gap[k] == own.to_dict()[k], k
    assert own.provisional and "with a provisional baseline" in own.text   # runs 1-2
