"""Damaged candump logs of a real lockstep bus run through `bench decode`, `bench hums
report` and `bench gap`: one TPDO1 line or one SYNC line
removed, every line twice, the lines shuffled, the log cut to 3 rows, a long gap. The
damage is counted and printed, short gaps are bridged (the indexes and the gap verdict of
the intact log stay), long ones make what needs them unavailable, no verdict without its
index."""

from __future__ import annotations

import contextlib
import io
import json
import os
import random
import subprocess
from pathlib import Path

import numpy as np
import pytest
from bus_helpers import bench

from bench.bus.logs import trace_from_log
from bench.cli import main


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Two lockstep 2 s sine logs (with and without sensor noise) and damaged copies."""
    d = tmp_path_factory.mktemp("damaged")
    env = {**os.environ, "BENCH_STATE_DIR": str(d / "state")}
    for name, extra in (("good", ()), ("clean", ("--set", "sensors.noise=off"))):
        r = bench("run", "sine", "--pace", "sync", "--duration", "2", *extra,
                  "--log", str(d / f"{name}.log"), env=env, timeout=180)
        assert r.returncode == 0, r.stderr
    for name in ("good", "clean"):
        lines = (d / f"{name}.log").read_text().splitlines()
        sync = [i for i, s in enumerate(lines) if " 080#" in s]
        tpdo1 = [i for i, s in enumerate(lines) if " 190#" in s]

        def keep(drop: set[int], out: str, src: list[str] = lines, name: str = name) -> None:
            (d / f"{name}_{out}.log").write_text(
                "\n".join(s for i, s in enumerate(src) if i not in drop) + "\n")
        keep({tpdo1[700]}, "drop_tpdo1")
        keep({sync[500]}, "drop_sync")
        keep(set(range(sync[500], sync[501])), "drop_period")
        keep(set(range(sync[800], sync[830])), "drop_30_periods")
        keep(set(tpdo1[600:720]), "drop_120_tpdo1")
        keep(set(range(sync[3], len(lines))), "three")
        (d / f"{name}_dup.log").write_text("".join(s + "\n" + s + "\n" for s in lines))
        shuffled = list(lines)
        random.Random(9).shuffle(shuffled)
        (d / f"{name}_shuffled.log").write_text("\n".join(shuffled) + "\n")
    return d


@pytest.fixture(scope="module")
def good(logs):
    """The intact log, decoded once for the file: its trace and `bench decode`'s output."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(["decode", str(logs / "good.log")])
    return trace_from_log(logs / "good.log"), rc, out.getvalue()


VALUES = ("setpoint_position_m", "mode", "current_demand_a", "current_a", "motor_speed_rad_s",
          "motor_angle_rad", "position_m", "status_word")


@pytest.mark.parametrize("variant, phrase, same", [
    ("drop_tpdo1", "missing: EMA_TPDO1 in 1 period", ()),
    ("drop_sync", "1 lost SYNC (1 recovered from its frames)", VALUES),
    ("dup", "{lines} duplicate frames dropped", VALUES + ("bus_time_s",)),
    ("shuffled", "frames out of time order: decoded in time-stamp order",
     VALUES + ("bus_time_s",)),
])
def test_decode_counts_the_damage(logs, good, capsys, variant, phrase, same):
    good, rc, good_out = good
    assert rc == 0
    assert "no lost, missing, duplicate or out-of-order frame" in good_out
    assert main(["decode", str(logs / f"good_{variant}.log")]) == 0
    out = capsys.readouterr().out
    phrase = phrase.format(lines=len((logs / "good.log").read_text().splitlines()))
    assert phrase in out and "2000 SYNC periods" in out and "1 run(s)" in out, out
    tr = trace_from_log(logs / f"good_{variant}.log")
    assert len(tr) == len(good) == 2000
    for c in same:
        np.testing.assert_array_equal(tr[c], good[c], err_msg=c)


def test_hums_report_bridges_counts_and_keeps_the_intact_numbers(logs, tmp_path, capsys):
    names = ["good", "good_drop_tpdo1", "good_drop_sync", "good_dup", "good_shuffled"]
    rc = main(["hums", "report", *[str(logs / f"{n}.log") for n in names], "--no-rul",
               "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0, out
    js = {x["log"]: x for x in json.loads((tmp_path / "indexes.json").read_text())}
    ref = js["good.log"]["indexes"]
    for n in names[1:]:
        x = js[f"{n}.log"]
        assert x["verdict"] == js["good.log"]["verdict"] == "HEALTHY"
        for k in ("ci", "ci_harmonic", "cp", "peak_ratio", "lost_motion_m"):
            assert x["indexes"][k] == pytest.approx(ref[k], abs=1e-6), (n, k)
    assert "good_drop_tpdo1.log: log: missing: EMA_TPDO1 in 1 period; short gaps bridged " \
           "by interpolation: current_a 1 sample" in out
    assert "good_drop_sync.log: log: 1 lost SYNC (1 recovered from its frames)" in out
    n = len((logs / "good.log").read_text().splitlines())
    assert f"good_dup.log: log: {n} duplicate frames dropped" in out
    assert "good.log: log:" not in out


@pytest.mark.parametrize("variant, reason", [
    ("three", "Ci not available (3 rows, at least 100 needed)"),
    ("drop_120_tpdo1", "Ci not available: 120 samples missing in current_a (longest gap "
                       "120 samples at t = 0.600 s"),
])
def test_hums_report_gives_no_verdict_without_its_index(logs, tmp_path, capsys, variant,
                                                        reason):
    rc = main(["hums", "report", str(logs / f"good_{variant}.log"), "--no-rul",
               "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert rc == 3
    assert f"good_{variant}.log: UNKNOWN; {reason}" in out, out
    assert err.startswith(f"error: no verdict for good_{variant}.log") and \
        len(err.splitlines()) == 1


def _gap(path: Path, capsys) -> subprocess.CompletedProcess:
    """`bench gap LOG` in this process (the command's start-up, numba's and scipy's
    imports, paid once for the file, not once a log)."""
    rc = main(["gap", str(path), "--workers", "1", "-q"])
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(["bench", "gap", str(path)], rc, out, err)


@pytest.mark.parametrize("variant", ["", "_drop_sync", "_drop_period"])
def test_gap_noise_free_log_with_a_lost_sync_has_no_significant_gap(logs, variant, capsys):
    r = _gap(logs / f"clean{variant}.log", capsys)
    assert r.returncode == 0, r.stderr
    assert "significant gap: no" in r.stdout, r.stdout
    if variant == "_drop_sync":
        assert "log: 1 lost SYNC (1 recovered from its frames)" in r.stdout
    if variant == "_drop_period":
        assert "short gaps bridged by interpolation: " in r.stdout


def test_gap_refuses_a_gap_it_cannot_bridge(logs, capsys):
    r = _gap(logs / "clean_drop_30_periods.log", capsys)
    assert r.returncode == 2
    assert r.stderr.startswith("error: gap diagnosis: 30 samples missing in")
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_a_log_of_another_node_is_one_line_not_a_table_of_nothing(logs, capsys):
    """`bench decode LOG --node-id 0x11` on node 0x10's log exited 0 with 2000 empty rows,
    "0 run(s)" and "no lost, missing, duplicate or out-of-order frame"."""
    assert main(["decode", str(logs / "good.log"), "--node-id", "0x11"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {logs / 'good.log'}: 2000 SYNC periods but not one "
                          "frame of node 0x11")
    assert len(err.strip().splitlines()) == 1
    assert main(["decode", str(logs / "good.log"), "--node-id", "0x10"]) == 0
