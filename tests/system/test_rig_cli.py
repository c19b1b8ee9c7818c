"""A new user's sequence on a real rig's 25 Hz table, each command a
subprocess: bench import -> bench calibrate --actuator -> bench gap -> bench hums report.
The calibration's model stays above the noise floor on the held-out cycle, so calibrate
writes the healthy baseline beside it and gap and the report judge against it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "tests" / "data" / "cranfield_sample"


def bench(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True,
                          text=True, timeout=300, cwd=cwd)


def test_import_calibrate_gap_hums_report(tmp_path):
    for table, out in (("normal_load40_runs1-4.csv.xz", "n"), ("spalling5_load40_runs1-2.csv.xz",
                                                               "s")):
        r = bench("import", str(SAMPLE / table), "--map",
                  str(ROOT / "bench" / "rig" / "actuators" / "cranfield_map.json"),
                  "--split-by", "load,run,group", "-o", out, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
    fit = [f"n/load=40_run={r}_group={g}.parquet" for r, gs in ((1, (51, 52, 53)),
                                                                (2, (56, 57, 58))) for g in gs]
    r = bench("calibrate", *fit, "--actuator", "cranfield", "--holdout",
              "n/load=40_run=3_group=61.parquet", "-o", "cal.json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "reproduces the healthy logs within 2 x the noise floor: no" in r.stdout
    assert "healthy baseline written: cal.baseline.json" in r.stdout
    assert json.loads((tmp_path / "cal.json").read_text())["baseline"]["file"] == \
        "cal.baseline.json"
    r = bench("gap", "s/load=40_run=1_group=51.parquet", "--nominal", "cal.json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert ("judged against the healthy baseline cal.baseline.json (runs 1,2, load 40 kgf, "
            "6 cycles)") in r.stdout
    assert "verdict: 1 / 1 cycle(s) flagged (periodic 1)" in r.stdout
    r = bench("hums", "report", "s/load=40_run=1_group=51.parquet", "--nominal", "cal.json",
              "--out", "rep", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "load=40_run=1_group=51.parquet: DEGRADED" in r.stdout
    assert "judged against the healthy baseline cal.baseline.json" in r.stdout
    page = (tmp_path / "rep" / "report.html").read_text()
    assert "data:image/png;base64," in page and "Not available on this log" in page
