"""The use-driven synthetic fleet with the real flight simulation: the life one flight
consumes rises with severity; the same seed writes the same logs and truth; the status
as of a date (`bench fleet status --as-of`) ignores the later tests."""

from __future__ import annotations

import json

import numpy as np

from bench.cli import main
from bench.fleet import synth as S


def test_flight_life_rises_with_severity():
    table = S.flight_life_table()
    life = np.array([table[s] for s in S.SEVERITY_GRID])
    assert np.all(life > 0) and np.all(np.diff(life) > 0)
    # the aero hinge load grows with deflection: at least x5 from severity 0.5 to 1.75
    assert life[-1] > 5 * life[0]


def test_same_seed_same_logs_and_truth_and_status_as_of(tmp_path, capsys):
    for run in ("a", "b"):
        assert main(["fleet", "synth", "--actuators", "1", "--days", "3", "--out",
                     str(tmp_path / run), "--seed", "4", "--workers", "1"]) == 0
    logs = {run: sorted((tmp_path / run).rglob("*.log")) for run in ("a", "b")}
    assert len(logs["a"]) == 3
    assert [p.read_bytes() for p in logs["a"]] == [p.read_bytes() for p in logs["b"]]
    ta, tb = ((tmp_path / r / "fleet-truth.json").read_text() for r in ("a", "b"))
    assert ta == tb
    row = json.loads(ta)["fleet"][0]
    assert row["flights"][0] > 0 and row["life_consumed"][0] > 0 and row["s"][0] == 0.0
    db = str(tmp_path / "f.duckdb")
    assert main(["fleet", "ingest", str(tmp_path / "a"), "--db", db, "--workers", "1"]) == 0
    capsys.readouterr()
    assert main(["fleet", "status", "--db", db, "--as-of", "2026-01-06"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and lines[1].split()[:2] == ["EMA-0000", "2"]
    assert "2026-01-06" in lines[1]
    assert main(["fleet", "status", "--db", db, "--as-of", "2026-01-01"]) == 0
    assert "no runs in the store up to 2026-01-01" in capsys.readouterr().out
    assert main(["fleet", "status", "--db", db, "--as-of", "soon"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --as-of")
