"""One verdict for one cycle: the study's judgement of a cycle (flagged, the signature
named, the fault family) is the one `bench gap` gives the same cycle, imported from the
same table, against the baseline the study wrote (baseline.json with its thresholds).
Built from the Cranfield sample: healthy runs 1-2 calibrate, 3-4 are held out, and the
spall table's ten cycles are judged."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from sample_data import SAMPLE, import_cycles

from bench.cli import main
from bench.rig.features import assess
from bench.rig.study import run_study

TABLES = ("normal_load40_runs1-4.csv.xz", "spalling5_load40_runs1-2.csv.xz")


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("oneverdict")
    (d / "tables").mkdir()
    for t in TABLES:
        shutil.copy(SAMPLE / t, d / "tables" / t)
        import_cycles(t, d / t.split("_")[0])
    st = run_study(d / "tables", [1, 2], [3, 4], workers=1, progress=False, lead_mm=5.0,
                   supervised=False)
    st.baseline.save(d / "baseline.json")     # as `bench rig study` writes it
    return d, st


def _gap(d: Path, cond: str, run: int, group: int, tmp_path: Path) -> dict:
    log = d / cond.split("_")[0] / f"load=40_run={run}_group={group}.parquet"
    out = tmp_path / f"{cond}_{run}_{group}.json"
    assert main(["gap", str(log), "--baseline", str(d / "baseline.json"), "--json",
                 str(out), "-q"]) == 0
    js = json.loads(out.read_text())
    assert js["against"] == "baseline" and len(js["verdicts"]) == 1
    return js["verdicts"][0]      # type: ignore[no-any-return]


@pytest.mark.parametrize("cond", ["normal_load40_runs1-4", "spalling5_load40_runs1-2"])
def test_the_study_and_bench_gap_give_each_cycle_one_verdict(study, cond, tmp_path):
    d, st = study
    name = st.healthy_condition if cond.startswith("normal") else cond
    thr = st.calibrations[40.0].thresholds
    rows = st.results[name][40.0]
    assert len(rows) == 10                          # held-out runs 3-4, or the spall's
    flagged = 0
    for r in rows:
        f = r.features
        mine = assess(f, thr)
        gap = _gap(d, cond, f.run, f.group, tmp_path)
        assert (gap["flagged"], gap["effect"], gap["fault"]) == (
            mine.flagged, mine.effect, mine.fault), f.label
        assert gap["level"] == ("DEGRADED" if mine.flagged else "HEALTHY"), f.label
        flagged += mine.flagged
    if cond.startswith("spalling"):
        assert flagged >= 8          # the spall is found: the comparison is not vacuous
