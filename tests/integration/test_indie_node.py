"""`bench run` over the loopback hub in lockstep against the independent actuator's node
(`python -m indie_plant`, which knows only ema_contract): the run completes, the ECU
reports the optional objects the node lacks, and the log decodes through the DBC to the
signals the actuator's own sensors give (an independent "real")."""

from __future__ import annotations

import numpy as np
import pytest
from bus_helpers import bench, make_env, start_node

from bench.bus.logs import trace_from_log
from bench.bus.procs import Child


def start_indie(cfg: dict, state, *args: str) -> Child:
    return start_node("indie", ["-m", "indie_plant"], cfg, state, *args)


@pytest.fixture(scope="module")
def indie_env(tmp_path_factory):
    state = tmp_path_factory.mktemp("state")
    env = make_env("loopback", state, plant=False)
    try:
        env.children.append(start_indie(env.cfg, state, "--load-n", "1000"))
        yield env
    finally:
        env.stop()


def test_lockstep_run_against_the_independent_node(indie_env, tmp_path):
    log = tmp_path / "indie.log"
    r = bench("run", "sine", "--duration", "1.0", "--pace", "sync", "--no-plant",
              "--no-progress", "--log", str(log), *indie_env.flags,
              env=indie_env.env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert "0x2000" in r.stderr or "plant parameter objects" in r.stderr   # said missing
    tr = trace_from_log(log)
    n = len(tr)
    assert 950 <= n <= 1010, n
    pos = np.asarray(tr["position_m"])
    sp = np.asarray(tr["setpoint_position_m"])
    assert np.all(np.isfinite(pos[5:]))
    # the nut follows the sine (the bench's ECU closes the loops over the bus)
    assert np.ptp(pos) > 0.5 * np.ptp(sp) > 0
    assert np.sqrt(np.mean((pos - sp) ** 2)) < 0.6 * np.ptp(sp)
    # the actuator's own sensors: the current ADC step (19.5 mA) shows in the log
    cur = np.asarray(tr["current_a"])
    steps = np.diff(np.unique(np.round(cur / (80.0 / 4096)) * (80.0 / 4096)))
    assert np.allclose(cur, np.round(cur / (80.0 / 4096)) * (80.0 / 4096), atol=2e-4)
    assert steps.size > 3
    # the rig's load reaches the log through the load cell (TPDO3)
    assert np.nanmax(np.abs(tr["load_force_n"])) > 300.0
