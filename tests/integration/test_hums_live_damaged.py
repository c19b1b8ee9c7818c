"""`LiveHums` (`bench hums watch`) on damaged logs gives the numbers and the verdict of
`bench hums report` for every command period (one row assembler, one verdict):
one TPDO1 line dropped, every line twice, one SYNC line dropped."""

from __future__ import annotations

import os

import numpy as np
import pytest
from bus_helpers import bench

from bench.bus.logs import read_log, trace_from_log
from bench.hums import report as R
from bench.hums.live import LiveHums
from bench.hums.verdict import judge


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A lockstep 4-period sine log with 50 um of backlash and damaged copies."""
    d = tmp_path_factory.mktemp("live_damaged")
    env = {**os.environ, "BENCH_STATE_DIR": str(d / "state")}
    r = bench("run", "sine", "--cycles", "4", "--pace", "sync", "--set",
              "effects.backlash_m=50e-6", "--log", str(d / "worn.log"), env=env, timeout=180)
    assert r.returncode == 0, r.stderr
    lines = (d / "worn.log").read_text().splitlines()
    sync = [i for i, s in enumerate(lines) if " 080#" in s]
    tpdo1 = [i for i, s in enumerate(lines) if " 190#" in s]

    def keep(drop: int, out: str) -> None:
        (d / f"{out}.log").write_text("\n".join(s for i, s in enumerate(lines) if i != drop)
                                      + "\n")
    keep(tpdo1[len(tpdo1) // 2], "drop_tpdo1")
    keep(sync[len(sync) // 2], "drop_sync")
    (d / "twice.log").write_text("".join(s + "\n" + s + "\n" for s in lines))
    return d


KEYS = ("cp", "ci", "ci_harmonic", "peak_ratio", "mean_error_m", "lost_motion_m")


@pytest.mark.parametrize("name", ["worn", "drop_tpdo1", "twice", "drop_sync"])
def test_live_equals_the_report_per_period(logs, name):
    log = logs / f"{name}.log"
    hums = LiveHums(0.5)
    live = hums.feed_all(read_log(log)) + hums.finish()
    a = R.analyse(trace_from_log(log), name, rul=False, period_s=0.5)
    table = a.period_table
    assert len(live) == len(table["cp"]) == 4
    for key in KEYS:
        got = np.array([getattr(r.indexes, key) for r in live])
        # lost motion: a streaming filter against the whole-signal one (~1e-14 apart)
        np.testing.assert_allclose(got, table[key], rtol=1e-12 if key == "lost_motion_m"
                                   else 0, err_msg=key)
    # the same verdict the report's verdict function gives that period
    for r in live:
        assert r.verdict == judge(r.indexes, 1) and r.level.name == "WARNING"
    # damage counted as the log decoder counts it
    meta = trace_from_log(log).meta
    for k in ("sync_gaps", "sync_recovered", "duplicate_frames", "replaced_frames"):
        assert hums.count[k] == meta[k], k


def test_live_same_as_intact_log_on_damaged_ones(logs):
    def ci(name):
        return [r.indexes.ci for r in LiveHums(0.5).feed_all(read_log(logs / f"{name}.log"))]
    intact = ci("worn")
    assert len(intact) == 4
    assert ci("twice") == intact
    assert ci("drop_sync") == intact
