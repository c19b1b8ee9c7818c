"""Every HTML report shows one value per quantity: each page's summary table (class
``summary``, one per page) against the JSON the same command writes, value for value,
each number as the JSON's value rounded to the digits the page shows. The HUMS report of
two simulated logs, the rig HUMS report of two Cranfield cycles, the rig study of the
Cranfield sample, the gap report of the worn log, and the fleet report of a synthetic
fleet (2 actuators x 3 days)."""

from __future__ import annotations

import json
import math

import pytest
from page_tables import numbers, shows, summary
from sample_data import SAMPLE, cranfield_folder, sine_logs

from bench.cli import main


def _one_number(cell: str) -> str:
    got = numbers(cell)
    assert len(got) == 1, cell
    return got[0]


@pytest.fixture(scope="module")
def sim_logs(tmp_path_factory):
    return sine_logs(tmp_path_factory.mktemp("logs"))


def test_hums_report(sim_logs, tmp_path):
    out = tmp_path / "hums"
    assert main(["hums", "report", str(sim_logs / "healthy.npz"), str(sim_logs / "worn.npz"),
                 "--no-rul", "--out", str(out)]) == 0
    js = json.loads((out / "indexes.json").read_text())
    rows = summary(out / "report.html")
    assert [r["log"] for r in rows] == [x["log"] for x in js] == ["healthy.npz", "worn.npz"]
    for row, x in zip(rows, js, strict=True):
        s = x["summary"]
        assert row["command"] == s["command"] and row["verdict"] == s["verdict"] == x["verdict"]
        for col, key in (("duration (s)", "duration_s"), ("Ci", "ci"), ("Cp", "cp"),
                         ("lost motion (um)", "lost_motion_um")):
            assert shows(_one_number(row[col]), s[key]), (col, row[col], s[key])
        assert s["ci"] == x["indexes"]["ci"]                   # the one Ci
        assert x["rul"].startswith(row["RUL (s) [90 % band]"])


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    return cranfield_folder(tmp_path_factory.mktemp("rig"))


def test_rig_hums_report(rig, tmp_path):
    out = tmp_path / "righums"
    logs = [rig / "s" / "load=40_run=1_group=51.parquet",
            rig / "n" / "load=40_run=3_group=61.parquet"]
    assert main(["hums", "report", *map(str, logs), "--baseline", str(rig / "base.json"),
                 "--out", str(out)]) == 0
    js = json.loads((out / "indexes.json").read_text())
    rows = summary(out / "report.html")
    assert len(rows) == len(js) == 2
    for row, x in zip(rows, js, strict=True):
        s = x["summary"]
        assert row["log"] == s["log"] == x["log"]
        assert row["verdict"] == s["verdict"] == x["verdict"]
        assert row["judged against"] == s["judged_against"] == x["judged_against"]
        assert int(row["samples"]) == s["samples"] > 0
        assert shows(_one_number(row["duration (s)"]), s["duration_s"])
    assert {r["verdict"] for r in rows} == {"DEGRADED", "HEALTHY"}


def _rate_cells(cell: str, rates: list[float]) -> None:
    got = numbers(cell)
    assert len(got) == len(rates), (cell, rates)
    assert all(shows(t, v, 100.0) for t, v in zip(got, rates, strict=True)), (cell, rates)


def test_rig_study(tmp_path):
    out = tmp_path / "study"
    assert main(["rig", "study", str(SAMPLE), "--calibrate-runs", "1,2", "--holdout-runs",
                 "3,4", "--lead-mm", "5", "--workers", "1", "--out", str(out)]) == 0
    sm = json.loads((out / "study.json").read_text())
    g, b = sm["goals"], sm["supervised"]["validation"]["bench"]
    rows = {r["goal"]: r for r in summary(out / "report.html")}
    fa = rows["healthy cycles flagged, per load, cross-validated"]
    (load, v), = g["false_alarms"].items()
    assert numbers(fa["result (95 % interval)"])[0] == load
    _rate_cells(fa["result (95 % interval)"].partition(" kgf ")[2], [v["rate"], *v["rate_95"]])
    assert fa["met"] == ("yes" if v["rate"] <= 0.05 else "no")
    d = g["detected"]
    _rate_cells(rows["fault cycles detected"]["result (95 % interval)"],
                [d["rate"], *d["rate_95"]])
    n = g["named"]
    named = rows["physics name right on flagged fault cycles, pooled and per family"]
    _rate_cells(named["result (95 % interval)"],
                [n["rate"], *n["rate_95"], *(f["rate"] for f in n["per_family"].values())])
    _rate_cells(rows["supervised, leaving runs out"]["result (95 % interval)"],
                [b["rate"], *b["rate_95"], b["least_recall"]])
    assert len(rows) == 4


def test_gap_report(sim_logs, tmp_path):
    out = tmp_path / "gap"
    assert main(["gap", str(sim_logs / "worn.npz"), "--effects", "backlash,friction",
                 "--workers", "1", "--report", str(out), "--json", str(tmp_path / "g.json")]) == 0
    js = json.loads((out / "gap.json").read_text())
    assert js == json.loads((tmp_path / "g.json").read_text())
    rows = summary(out / "index.html")
    assert len(rows) == len(js["ranking"]) >= 2
    for row, c in zip(rows, js["ranking"], strict=True):
        assert int(row["#"]) == c["rank"]
        assert row["effect"] == c["effect"] + (" (chosen)" if c.get("chosen") else "")
        parts = row["parameters (95 % CI)"].split("; ")
        assert len(parts) == len(c["params"])
        for part, (name, p) in zip(parts, c["params"].items(), strict=True):
            assert part.startswith(f"{name} = ")
            value, _, interval = part.partition(" = ")[2].partition(" [")
            lo, _, hi = interval.partition("]")[0].partition(", ")
            shown = [(t, x) for t, x in zip((value, lo, hi), (p["value"], *p["ci95"]),
                                            strict=True) if t != "bound"]
            assert any(all(shows(_one_number(t), x, k) for t, x in shown)
                       for k in (1.0, 1e3, 1e6)), (part, p)
        shrink = next(v for k, v in row.items() if k.startswith("held-out shrink"))
        assert shows(shrink, c["heldout_shrink_pct"])
        before, after = numbers(row["held-out gap (x floor, RMS)"])
        assert shows(before, c["gap_before"]["normalised"])
        assert shows(after, c["gap_after"]["normalised"])
        assert shows(row["BIC"], c["score"]["bic"])
        assert row["suspect"] == "; ".join(c["suspect"])
    assert sum(r["effect"].endswith("(chosen)") for r in rows) == 1


def test_fleet_report(tmp_path):
    logs, db, out = tmp_path / "logs", str(tmp_path / "f.duckdb"), tmp_path / "rep"
    assert main(["fleet", "synth", "--actuators", "2", "--days", "3", "--out", str(logs),
                 "--seed", "5", "--workers", "1"]) == 0
    assert main(["fleet", "ingest", str(logs), "--db", db, "--workers", "1"]) == 0
    assert main(["fleet", "report", "--db", db, "--out", str(out)]) == 0
    js = json.loads((out / "status.json").read_text())
    rows = summary(out / "index.html")
    assert [r["actuator"] for r in rows] == [x["actuator"] for x in js]
    assert sorted(r["actuator"] for r in rows) == ["EMA-0000", "EMA-0001"]
    for row, x in zip(rows, js, strict=True):
        assert int(row["tests"]) == x["tests"] == 3
        assert row["last test (UTC)"] == x["last_test_utc"]
        assert row["level"] == x["level"]
        assert shows(row["Ci"], x["ci"])
        slope = row["trend Ci/day"]
        assert shows(slope, x["slope_ci_per_day"]) if slope != "-" else \
            x["slope_ci_per_day"] is None or not math.isfinite(x["slope_ci_per_day"])
        assert row["RUL (days)"] == x["rul"] and row["usage consumed"] == x["usage"]
    # each actuator's page: its summary, the same values
    for x in js:
        page = {r["quantity"]: r["value"]
                for r in summary(out / "actuators" / f"{x['actuator']}.html")}
        assert int(page["tests"]) == x["tests"] and shows(page["Ci (last)"], x["ci"])
        assert page["last test (UTC)"] == x["last_test_utc"]
        assert page["RUL (days) [90 % band]"] == x["rul"]
        assert page["usage consumed"] == x["usage"]
        assert page["last verdict"] == f"{x['level']}: {x['reasons']}"
