"""The gap commands end to end in subprocesses: --help, bench import -> bench calibrate ->
bench gap (JSON, report), gap-bench smoke run, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from bench.gap.resim import FAST
from bench.profiles.maneuvers import compact
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


def bench(*args: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True,
                          text=True, timeout=timeout)


@pytest.mark.parametrize("cmd", ["gap", "gap-bench", "calibrate", "import"])
def test_help(cmd):
    r = bench(cmd, "--help")
    assert r.returncode == 0, r.stderr
    assert "usage:" in r.stdout


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("gap")
    base = PlantParams().with_dict({**FAST, "sensors.noise": True})
    healthy = simulate(compact(), base.with_dict({"sensors.noise_seed": 3})).measured()
    worn = simulate(compact(), base.with_dict({"sensors.noise_seed": 4,
                                               "effects.backlash_m": 40e-6})).measured()
    # the healthy log as another rig's table: ms, mm, rpm, mA, degrees
    t = healthy.t
    rows = ["time_ms,lvdt_mm,enc_rpm,enc_deg,i_ma,idem_a,sp_mm,mode,load_kn"]
    for k in range(len(t)):
        rows.append(",".join(repr(float(x)) for x in (
            t[k] * 1e3, healthy["position_m"][k] * 1e3,
            healthy["motor_speed_rad_s"][k] * 60 / (2 * np.pi),
            np.degrees(healthy["motor_angle_rad"][k]), healthy["current_a"][k] * 1e3,
            healthy["current_demand_a"][k], healthy["setpoint_position_m"][k] * 1e3,
            healthy["mode"][k], healthy["load_force_n"][k] * 1e-3)))
    (d / "rig.csv").write_text("\n".join(rows) + "\n")
    (d / "map.csv").write_text(
        "signal,column,unit,scale\nt_s,time_ms,ms,1\nposition_m,lvdt_mm,mm,1\n"
        "motor_speed_rad_s,enc_rpm,rpm,1\nmotor_angle_rad,enc_deg,deg,1\n"
        "current_a,i_ma,mA,1\ncurrent_demand_a,idem_a,A,1\n"
        "setpoint_position_m,sp_mm,mm,1\nmode,mode,-,1\nload_force_n,load_kn,kN,1\n")
    worn.save(d / "worn.npz")
    return d


def test_import_calibrate_gap(logs):
    r = bench("import", str(logs / "rig.csv"), "--map", str(logs / "map.csv"), "-o",
              str(logs / "healthy.npz"))
    assert r.returncode == 0, r.stderr
    assert "4000 samples" in r.stdout
    from bench.signals.trace import Trace
    imported = Trace.load(logs / "healthy.npz")
    assert np.max(np.abs(imported["load_force_n"])) > 1900.0     # the 2 kN load, in N
    r = bench("calibrate", str(logs / "healthy.npz"), "--params",
              "motor.inertia_kg_m2,effects.friction_scale,sensors.encoder_gain",
              "-o", str(logs / "cal.json"))
    assert r.returncode == 0, r.stderr
    cal = json.loads((logs / "cal.json").read_text())
    assert cal["params"]["motor.inertia_kg_m2"] == pytest.approx(4e-3, rel=0.05)
    assert cal["params"]["sensors.encoder_gain"] == pytest.approx(1.0, abs=0.01)
    r = bench("gap", str(logs / "worn.npz"), "--nominal", str(logs / "cal.json"),
              "--effects", "backlash,kt,lvdt_lag", "--workers", "1", "-q",
              "--json", str(logs / "gap.json"), "--report", str(logs / "report"))
    assert r.returncode == 0, r.stderr
    assert "verdict: backlash" in r.stdout
    js = json.loads((logs / "gap.json").read_text())
    from bench.gap.result_json import GAP_KEYS
    assert set(js) == set(GAP_KEYS) and js["against"] == "model"
    assert js["verdict"]["effect"] == "backlash" and js["verdict"]["level"] == "DEGRADED"
    assert js["reference"] == js["verdict"]["reference"] == "thesis model, calibration cal.json"
    assert (logs / "report" / "index.html").exists()
    assert (logs / "report" / "traces_before_after.png").exists()


def test_gap_bench_smoke(tmp_path):
    r = bench("gap-bench", "--cases", "1", "--seed", "3", "--log-s", "4", "--workers", "1",
              "--effects", "backlash,kt,encoder_gain", "--json", str(tmp_path / "b.json"))
    assert r.returncode == 0, r.stderr
    out = json.loads((tmp_path / "b.json").read_text())
    assert out["cases"] == 1 and len(out["results"]) == 1
    assert "| metric | result | goal |" in r.stdout


@pytest.mark.parametrize("args, msg", [
    (["gap", "nosuch.npz"], "error: no such file: nosuch.npz"),
    (["gap", "--effects", "backlash,ripple", "y.npz"], "error: unknown effect 'ripple'"),
    (["gap"], "error: bench gap needs a log"),
    (["import", "nosuch.csv", "--map", "nosuch.json"], "error: no such map file"),
])
def test_errors_are_one_line(args, msg):
    r = bench(*args)
    assert r.returncode == 2
    assert r.stderr.strip().startswith(msg), r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
