"""`bench usage` on the Cranfield sample (tests/data/cranfield_sample, PROVENANCE.md)
imported with `bench import` (CLI in-process): a 25 Hz linear potentiometer with about
0.3 mm of noise, where the default 20 um position hysteresis let rainflow count noise
(29 cycles on one out-and-back stroke, 144 on a run of five). With the noise rule
(docs/usage.md, "Hysteresis") each 120 mm out-and-back stroke is one cycle."""

from __future__ import annotations

import csv
import io
import json
import lzma
from pathlib import Path

import pytest

from bench.bus.logs import load_trace
from bench.cli import main
from bench.usage import UsageSettings, usage_of_trace

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "tests" / "data" / "cranfield_sample" / "normal_load40_runs1-4.csv.xz"
MAP = ROOT / "bench" / "rig" / "actuators" / "cranfield_map.json"
CYCLE = "load=40_run=1_group=51.parquet"
RUN = "load=40_run=1.parquet"


def off() -> UsageSettings:
    """The position setting alone, the rule off: the counts before the rule (built in
    the tests, so that on the code before the rule they fail on counts, not on a name)."""
    return UsageSettings(position_noise_factor=0.0)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """The healthy table's 20 cycles, one trace each (as docs/real-data.md imports them),
    and its 4 runs of 5 cycles, one trace each: the cycles' time restarts at 0, so the
    run table is the same rows with the time counted on over the run (40 ms a row)."""
    d = tmp_path_factory.mktemp("usage_rig")
    assert main(["import", str(TABLE), "--map", str(MAP), "--split-by", "load,run,group",
                 "-o", str(d / "cycles")]) == 0
    rows = list(csv.reader(io.StringIO(lzma.open(TABLE, "rt").read())))
    head = rows[0]
    t_col, run_col = head.index("time"), head.index("run")
    count: dict[str, int] = {}
    for r in rows[1:]:
        k = count[r[run_col]] = count.get(r[run_col], -1) + 1
        r[t_col] = f"{k * 0.04:.2f}"
    with open(d / "runs.csv", "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    assert main(["import", str(d / "runs.csv"), "--map", str(MAP), "--split-by", "load,run",
                 "-o", str(d / "runs")]) == 0
    return d


def test_one_stroke_is_one_cycle_not_a_noise_count(rig):
    tr = load_trace(rig / "cycles" / CYCLE)
    assert len(tr) == 324                               # 13 s at 25 Hz
    s = usage_of_trace(tr)
    assert s.position_cycles == 1.0                     # out and back: two half cycles
    assert 0.12 < s.position_range_max_m < 0.13         # the 120 mm stroke (and overshoot)
    assert s.position_rainflow[-1].sum() == 1.0         # both halves in the >= 50 mm bin
    assert s.hysteresis["position"] == \
        "3 mm = 10 x the log's position noise 0.3 mm (setting 20 um)"
    assert s.hysteresis["load"] == "100 N (setting; noise rule off: usage.load_noise_factor=0)"
    assert s.load_cycles == 0.0                         # a constant 40 kgf
    before = usage_of_trace(tr, off())
    assert before.position_cycles == 29.0               # noise-driven
    assert before.position_rainflow[-1].sum() == 1.0    # (the stroke is in it too)


def test_every_cycle_and_run_counts_its_strokes(rig):
    cycles = sorted((rig / "cycles").glob("*.parquet"))
    assert len(cycles) == 20
    after = [usage_of_trace(load_trace(p)) for p in cycles]
    before = [usage_of_trace(load_trace(p), off()).position_cycles for p in cycles]
    for s in after:                                     # one stroke of ~125 mm in each
        assert s.position_rainflow[-1].sum() == 1.0
        assert 2.3e-3 < s.position_hysteresis_m < 3.3e-3
    counts = [s.position_cycles for s in after]
    # 18 of 20 exactly 1; two (runs 3 and 4, groups 64 and 69) also count 1-2 cycles of
    # 2.4-3 mm in the dwell, where the position wanders more than its white-noise sigma
    assert counts.count(1.0) == 18 and sum(counts) == 23.0
    assert min(before) == 17.5 and sum(before) == 509.0
    runs = sorted((rig / "runs").glob("*.parquet"))
    assert [p.name for p in runs] == [f"load=40_run={r}.parquet" for r in (1, 2, 3, 4)]
    run_counts = [usage_of_trace(load_trace(p)).position_cycles for p in runs]
    assert run_counts == [5.0, 5.0, 7.0, 5.0]           # 5 strokes a run
    assert [usage_of_trace(load_trace(p), off()).position_cycles for p in runs] == [
        144.0, 132.5, 109.0, 121.0]


def test_the_cli_says_which_hysteresis_and_why(rig, tmp_path, capsys):
    out = tmp_path / "u.json"
    assert main(["usage", str(rig / "runs" / RUN), str(rig / "cycles" / CYCLE),
                 "--by-actuator", "--json", str(out)]) == 0
    text = capsys.readouterr().out.splitlines()
    assert f"{RUN}: hysteresis: reversal 2 um (setting; on the encoder angle, no noise " \
           "rule); position 3.03 mm = 10 x the log's position noise 0.303 mm (setting " \
           "20 um); load 100 N (setting; noise rule off: usage.load_noise_factor=0)" in text
    assert any(line.startswith("actuator unknown: hysteresis: reversal 2 um") and
               "position up to 3.03 mm; the runs differ" in line for line in text)
    doc = json.loads(out.read_text())
    run = doc["runs"][0]
    assert run["position_cycles"] == 5.0
    assert run["position_hysteresis_m"] == pytest.approx(3.03e-3, rel=1e-3)
    assert run["hysteresis"]["position"].startswith("3.03 mm = 10 x")
    assert doc["settings"]["position_hysteresis_m"] == 20e-6          # the setting
    assert doc["settings"]["position_noise_factor"] == 10.0
    # an explicit setting is a floor: raised by the noise rule, and said so
    assert main(["usage", str(rig / "cycles" / CYCLE), "--set",
                 "usage.position_hysteresis_m=1e-3"]) == 0
    assert "position 3 mm = 10 x the log's position noise 0.3 mm (setting 1 mm)" in \
        capsys.readouterr().out
    # the rule off: the setting alone, and the noise counted again
    assert main(["usage", str(rig / "cycles" / CYCLE), "--set",
                 "usage.position_noise_factor=0"]) == 0
    text = capsys.readouterr().out.splitlines()
    assert text[1].split()[7] == "29"
    assert "position 20 um (setting; noise rule off: usage.position_noise_factor=0)" in text[2]
