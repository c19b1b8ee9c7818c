"""The HUMS live on the bus (`bench hums watch`): per-command-period indexes of a run, as
a passive bus client, equal to the same indexes computed from the run's candump log."""

from __future__ import annotations

import csv
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from bus_helpers import BUS_KINDS, ROOT, module_bus_env, watch_a_run

from bench.bus.logs import read_log, trace_from_log
from bench.hums import monitor as M
from bench.hums.indexes import period_indexes
from bench.hums.live import LiveHums
from bench.hums.verdict import judged_ci
from bench.profiles.catalog import make_profile
from plant_rt.params import PlantParams


@pytest.fixture(scope="module", params=BUS_KINDS)
def bus_env(request, tmp_path_factory):
    yield from module_bus_env(request, tmp_path_factory)


def test_watch_reports_every_period_like_the_log(bus_env, tmp_path):
    out = tmp_path / "live.csv"
    values = {"effects.backlash_m": 50e-6, "sensors.noise": True, "sensors.noise_seed": 5}
    log = tmp_path / "run.log"
    _, rc, stdout, stderr = watch_a_run(bus_env, ["--out", str(out)],
                                        make_profile("sine", cycles=4), values, log)
    assert rc == 0, stderr
    assert "4 command periods over 1 run(s)" in stderr
    with open(out) as f:
        live = list(csv.DictReader(f))
    assert [int(r["period"]) for r in live] == [0, 1, 2, 3]
    # 50 um of backlash: every period below the thesis' warning level, none healthy
    assert all(r["level"] in ("WARNING", "DEGRADED") for r in live)
    assert "WARNING" in stdout

    # the same numbers from the log: replayed through LiveHums, and offline
    replay = LiveHums(0.5).feed_all(read_log(log))
    tr = trace_from_log(log)
    params = PlantParams()
    kp = M.fitted(params)[0].gain_rad_s_per_m
    nom = M.nominal_for(tr, kp, M.MonitorParams.from_plant(params))
    offline = list(period_indexes(tr, nom, 0.5, kin=None))
    assert len(offline) == len(replay) == 4
    for key, attr in (("cp", "cp"), ("ci_broadband", "ci"), ("ci_harmonic", "ci_harmonic"),
                      ("peak_ratio", "peak_ratio")):
        a = np.array([float(r[key]) for r in live])
        b = np.array([getattr(ix, attr) for ix in offline])
        np.testing.assert_allclose(a, b, rtol=1e-6, err_msg=key)
        c = np.array([getattr(r.indexes, attr) for r in replay])
        np.testing.assert_allclose(c, a, rtol=1e-9, err_msg=key)
    # the judged Ci: the CSV's `ci` and the printed "Ci", the one the level rests on
    ci = np.array([float(r["ci"]) for r in live])
    np.testing.assert_allclose(ci, [judged_ci(ix.ci, ix.ci_harmonic) for ix in offline],
                               rtol=1e-6)
    printed = [float(v) for v in re.findall(r"Ci +([0-9.]+)", stdout)]
    np.testing.assert_allclose(printed, ci, atol=5e-4)


def test_watch_without_a_bus_is_a_one_line_error(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    env["BENCH_STATE_DIR"] = str(tmp_path / "none")
    env["HOME"] = str(tmp_path)          # no ~/.canrc
    r = subprocess.run([sys.executable, "-m", "bench", "hums", "watch", "--duration", "1"],
                       capture_output=True, text=True, timeout=120, env=env, cwd=str(ROOT))
    if r.returncode == 0:
        pytest.skip("this machine has a configured bus (vcan0 or python-can config)")
    assert r.returncode == 2
    assert r.stderr.startswith("error: no bus to listen to")
    assert "Traceback" not in r.stderr
