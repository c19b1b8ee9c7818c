"""`bench hums` end to end in a subprocess: sweep JSON rows, fit, a short RUL run, the
HTML report of trace files, and one-line errors on logs that lack what a method needs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


def run_bench(*args: str, timeout: float = 240.0, env: dict | None = None
              ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", "hums", *args], capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, **(env or {})})


def test_sweep_writes_json_rows(tmp_path):
    out = tmp_path / "h.json"
    r = run_bench("sweep", "--points", "2", "--noise", "off", "--workers", "1",
                  "--json", str(out), "--figures", str(tmp_path / "fig"),
                  "--doc", str(tmp_path / "hums.md"))
    assert r.returncode == 0, r.stderr
    rows = json.loads(out.read_text())
    assert {"id", "quantity", "unit", "thesis", "project"} <= set(rows[0])
    ids = {row["id"] for row in rows}
    assert {"H1", "H2", "H3", "H4", "H5"} <= ids
    ci = next(row for row in rows if row["id"] == "H4" and row["quantity"].startswith("Ci fall"))
    assert 30 < ci["project"] < 60
    assert (tmp_path / "fig" / "h5_spectrum.png").stat().st_size > 10_000
    doc = (tmp_path / "hums.md").read_text()
    assert "<!-- sweep:begin -->" in doc and "| H4 |" in doc


def in_process(*args: str) -> int:
    from bench.cli import main
    return main(["hums", *args])


def test_fit_and_short_rul(tmp_path):
    assert in_process("fit", "--json", str(tmp_path / "fit.json")) == 0
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["converged"] and 600 < fit["gain_thesis_units"] < 720
    assert in_process("rul", "--no-fused", "--workers", "1", "--set",
                      "schedule.duration_s=30", "--json", str(tmp_path / "r.json")) == 0
    rows = json.loads((tmp_path / "r.json").read_text())
    assert any(row["id"] == "R2" and "predicted RUL" in row["quantity"] for row in rows)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("logs")
    worn = PlantParams().with_dict({"effects.backlash_m": 40e-6, "effects.friction_scale": 2.0,
                                    "sensors.noise": True, "sensors.noise_seed": 5})
    simulate(make_profile("sine", duration_s=3.0), worn).measured().save(d / "worn.npz")
    healthy = PlantParams().with_dict({"sensors.noise": True, "sensors.noise_seed": 6})
    tr = simulate(make_profile("sine", duration_s=3.0), healthy).measured()
    tr.meta.pop("fundamental_hz", None)
    tr.save(d / "healthy.csv")     # CSV keeps no metadata: f0 from the set-point spectrum
    cols = {k: v for k, v in tr.columns.items() if k not in ("current_a", "position_m")}
    from bench.signals.trace import Trace
    Trace(cols).save(d / "no_sensors.npz")
    (d / "bus.log").write_text("(0.000000) vcan0 181#0000000000000000\n")
    (d / "notes.txt").write_text("hello\n")
    return d


def test_report_is_self_contained_with_a_verdict(logs, tmp_path):
    out = tmp_path / "rep"
    r = run_bench("report", str(logs / "worn.npz"), str(logs / "healthy.csv"), "--no-rul",
                  "--out", str(out))
    assert r.returncode == 0, r.stderr
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") >= 4
    assert "src='http" not in page and "<script" not in page
    js = json.loads((out / "indexes.json").read_text())
    verdicts = {x["log"]: x["verdict"] for x in js}
    assert verdicts["healthy.csv"] == "HEALTHY"
    assert verdicts["worn.npz"] in ("DEGRADED", "WARNING")
    f0 = {x["log"]: x["fundamental_hz"] for x in js}
    assert f0["healthy.csv"] == pytest.approx(2.0, rel=1e-6)
    worn = next(x for x in js if x["log"] == "worn.npz")
    assert worn["indexes"]["ci"] < 0.93
    assert np.isfinite(worn["indexes"]["lost_motion_m"])


def test_report_errors_are_one_line(logs, tmp_path, capsys):
    r = run_bench("report", str(logs / "no_sensors.npz"), "--out", str(tmp_path))
    assert r.returncode == 2
    assert r.stderr.startswith("error:") and "current_a or position_m" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    cases = [(logs / "notes.txt", "unknown log format"), (logs / "missing.npz", "no such file")]
    try:
        import bench.bus.logs  # noqa: F401
    except ImportError:
        cases.append((logs / "bus.log", "bench.bus.logs"))
    for path, msg in cases:
        assert in_process("report", str(path), "--out", str(tmp_path)) == 2
        err = capsys.readouterr().err
        assert err.startswith("error:") and msg in err, err


@pytest.mark.parametrize("args, msg", [
    (("sweep", "--points", "1"), "2 to 201 degradation points"),
    (("sweep", "--workers", "0"), "--workers"),
    (("fit", "--set", "motor.resistance_ohm=-1"), "below its minimum"),
    (("report", "x.npz", "--period", "0"), "--period"),
])
def test_user_errors(args, msg, capsys):
    assert in_process(*args) == 2
    err = capsys.readouterr().err
    assert msg in err and err.startswith("error:"), err
    assert Path("x.npz").exists() is False
