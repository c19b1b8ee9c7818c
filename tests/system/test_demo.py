"""`bench demo`, the README's first command: the main job end to end, over the loopback
bus (lockstep) and in process, with fixed noise seeds."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from bench.bus.logs import trace_from_log


def _demo(tmp_path, *args: str) -> tuple[subprocess.CompletedProcess, dict]:
    out = tmp_path / "demo"
    env = {**os.environ, "BENCH_STATE_DIR": str(tmp_path / "state")}
    r = subprocess.run([sys.executable, "-m", "bench", "demo", "--out", str(out),
                        "--cycles", "2", *args], capture_output=True, text=True,
                       timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())   # strict JSON: no NaN
    return r, summary


def _verdicts(summary: dict) -> dict[str, str]:
    return {row["log"].split(".")[0]: row["verdict"] for row in summary["hums"]}


def test_demo_over_the_bus_logs_three_runs_and_grades_them(tmp_path):
    r, summary = _demo(tmp_path, "--no-gap")
    out = tmp_path / "demo"
    assert "over the bus, pace sync" in r.stdout
    v = _verdicts(summary)
    assert v["healthy"] == "HEALTHY"
    assert v["worn"] in ("DEGRADED", "WARNING")
    assert v["end-of-life"] == "FAILURE"
    ci = {row["log"].split(".")[0]: row["ci"] for row in summary["hums"]}
    assert ci["healthy"] > ci["worn"] > ci["end-of-life"]
    for name in ("healthy", "worn", "end-of-life"):
        tr = trace_from_log(out / f"{name}.log")
        assert len(tr) == pytest.approx(1000, abs=2)          # 2 periods of 2 Hz at 1 kHz
        assert np.isfinite(tr["current_a"]).all()
        params = tr.meta["params"]                            # read back by SDO
        want = {"healthy": 0.0, "worn": 50e-6, "end-of-life": 100e-6}[name]
        assert params["effects"]["backlash_m"] == pytest.approx(want)
    html = (out / "hums" / "report.html").read_text()
    assert "end-of-life.log" in html and "FAILURE" in html


def test_demo_in_process_agrees_with_the_bus_run_and_names_the_wear(tmp_path):
    r, summary = _demo(tmp_path, "--in-process")
    assert "in process (no bus)" in r.stdout
    v = _verdicts(summary)
    assert v == {"healthy": "HEALTHY", "worn": v["worn"], "end-of-life": "FAILURE"}
    gap = summary["gap"]
    assert gap is not None
    assert "backlash" in gap["verdict"]
    chosen = next(c for c in gap["ranking"] if c["chosen"])
    assert "backlash" in chosen["effect"]
    fitted = chosen["params"]["backlash_m"]["value"]
    assert fitted == pytest.approx(50e-6, rel=0.1)
    # the worn actuator's friction x2.5 inside the friction family's interval (before:
    # [2.22, 2.34], the fast model's bias and one correlation length for all signals)
    friction = [e for e in gap["finding"]["effects"] if e["family"] == "friction"]
    if friction:
        lo, hi = friction[0]["size"]["ci95"]
        assert lo <= 2.5 <= hi
