"""The ECU against a node that implements only CiA 301 and the PDOs of dbc/ema.dbc (the
test double `minimal_node.py`, a vendor's actuator): optional objects read when there,
reported missing when not, and the run goes on (docs/node-contract.md).

Real-time runs are tolerant only where real time makes them so (late TPDO sets on a
loaded machine): they must complete, without error, report every missing optional
object, and the nut must follow the set-point within a generous bound."""

from __future__ import annotations

import subprocess
import time
from collections import Counter
from pathlib import Path

import can
import canopen
import numpy as np
import pytest
from bus_helpers import bench, make_env, start_node
from canopen.sdo.exceptions import SdoAbortedError

from bench import BenchError
from bench.bus.logs import trace_from_log
from bench.bus.procs import Child
from bench.ecu import run_over_bus
from bench.profiles.catalog import make_profile
from bench.signals.trace import Trace
from bench.sim.harness import simulate
from ema_contract.frames import eds_path
from plant_rt.params import PlantParams

NODE = Path(__file__).resolve().parent / "minimal_node.py"
OPTIONAL = ["0x2000", "0x2001", "0x2002", "0x2003", "0x2004", "0x2005", "0x2006", "0x2007",
            "0x2008", "0x2100", "0x2200"]
QUANT = {"position_m": 1e-8, "current_a": 1e-4, "motor_speed_rad_s": 1e-4,
         "current_demand_a": 1e-4, "load_force_n": 2.0}


QUANT_TPDO = {"MotorCurrent": 1e-4, "EncoderAngle": 0.0, "EncoderSpeed": 1e-4,
              "LvdtPosition": 1e-8}


def closed_loop_mismatch(log: Path, profile) -> tuple[float, dict[str, float], int]:
    """Replay a run of the minimal node (default parameters) from its log.

    (1) Each RPDO1 demand the ECU sent against the controller's answer to the set-points
    of its period and the newest TPDO2/3 values logged before it: the ECU logs every
    frame as it sends or reads it, so the log's order is what the ECU knew. (2) Each
    TPDO set the node sent (the n-th set answers the n-th SYNC: one connection, frames
    in order) against the node's physics (`plant_rt.model.Plant`) at that SYNC, driven
    by the demand it had latched, the last RPDO1 before the SYNC. Returns the largest
    demand mismatch (A), the largest mismatch of each TPDO signal and the RPDOs seen."""
    from bench.ecu.period import float32_limit
    from bench.sim.control import Controller, ControllerParams
    from ema_contract.frames import Frames
    from plant_rt.model import Plant
    params = PlantParams()
    ts = params.sim.sync_period_s
    n = int(round(profile.duration_s / ts))
    sp_pos, sp_spd = profile.setpoints(np.arange(n) * ts)
    ctrl = Controller(ControllerParams(sample_period_s=ts))
    limit = float32_limit(params.motor.current_max_a)
    cpr = params.sensors.encoder_counts_per_rev
    plant, frames = Plant(params), Frames()
    names = {frames.cob[f]: f for f in ("EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3")}
    latest: dict[str, dict] = {}
    expected: list[dict[str, float]] = []
    got: dict[str, list[float]] = {k: [] for k in QUANT_TPDO}
    held, k, demand_err, n_rpdo = (0.0, 0), -1, 0.0, 0
    with can.LogReader(log) as reader:
        for msg in reader:
            cid = msg.arbitration_id
            if cid == frames.cob["SYNC"]:
                k += 1
                m = plant.measure()
                expected.append({"MotorCurrent": m.current_a, "EncoderSpeed":
                                 m.motor_speed_rad_s, "LvdtPosition": m.position_m,
                                 "EncoderAngle": round(m.motor_angle_rad * cpr / 2 / np.pi)})
                plant.step(held[0] if held[1] & 1 else 0.0)
            elif cid in names:
                sig = frames.decode(msg)[1]
                latest[names[cid]] = sig
                for key in QUANT_TPDO:
                    if key in sig:
                        got[key].append(float(sig[key]))
            elif cid == frames.cob["EMA_RPDO1"]:
                sig = frames.decode(msg)[1]
                want = ctrl.step(sp_pos[k], sp_spd[k], int(profile.mode),
                                 float(latest["EMA_TPDO3"]["LvdtPosition"]),
                                 float(latest["EMA_TPDO2"]["EncoderSpeed"]))
                want = float(np.float32(min(max(want, -limit), limit)))
                demand_err = max(demand_err, abs(want - float(sig["CurrentDemand"])))
                held, n_rpdo = (float(sig["CurrentDemand"]), int(sig["ControlWord"])), n_rpdo + 1
    sensor_err = {key: max(abs(g - e[key]) for g, e in zip(vals, expected, strict=False))
                  for key, vals in got.items()}
    return demand_err, sensor_err, n_rpdo


def start_minimal_node(cfg: dict, state: Path, *args: str) -> Child:
    """The test double as its own process on `cfg`; waits (bounded) until it is on the bus."""
    return start_node("minimal", [str(NODE)], cfg, state, *args)


@pytest.fixture(scope="module")
def node_env(tmp_path_factory):
    """A loopback hub with the minimal node (id 0x10) and nothing else on it."""
    state = tmp_path_factory.mktemp("state")
    env = make_env("loopback", state, plant=False)
    try:
        env.children.append(start_minimal_node(env.cfg, state))
        yield env
    finally:
        env.stop()


def one_line_error(r: subprocess.CompletedProcess) -> str:
    assert r.returncode != 0, r.stdout
    assert "Traceback" not in r.stderr, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert lines and lines[-1].startswith("error: "), r.stderr
    return lines[-1]


def test_the_double_has_only_cia301_objects(node_env):
    """The test double is what it claims: CiA 301 objects answer, the plant's do not."""
    net = canopen.Network()
    net.connect(**node_env.cfg)
    try:
        node = net.add_node(0x10, str(eds_path()))
        node.sdo.RESPONSE_TIMEOUT = 1.0
        assert node.sdo[0x1000].raw == 0
        assert node.sdo[0x1018][2].raw == 1           # product code of the EDS
        assert node.sdo[0x1006].raw == 1000           # SYNC period (us) of its physics
        assert node.sdo[0x1017].raw == 100
        for index, sub in ((0x2000, 1), (0x2003, 11), (0x2100, 1), (0x2200, 1)):
            with pytest.raises(SdoAbortedError) as exc:
                node.sdo.upload(index, sub)
            assert exc.value.code == 0x06020000, hex(index)
        node.nmt.wait_for_heartbeat(1.0)
    finally:
        net.disconnect()


def test_the_double_consumes_the_ecu_heartbeat(node_env):
    """0x1016: one ECU heartbeat, then silence: after 300 ms the node sends EMCY 0x8130
    (heartbeat lost) and reports it in 0x1001; NMT reset node clears it."""
    net = canopen.Network()
    net.connect(**node_env.cfg)
    try:
        node = net.add_node(0x10, str(eds_path()))
        node.sdo.RESPONSE_TIMEOUT = 1.0
        bootups: list[int] = []
        node.nmt.add_heartbeat_callback(lambda state: state == 0 and bootups.append(state))

        def reset_node() -> None:   # (canopen's wait_for_bootup misses an early boot-up)
            n = len(bootups)
            node.nmt.send_command(0x81)
            end = time.monotonic() + 3.0
            while len(bootups) == n:
                assert time.monotonic() < end, "no boot-up within 3 s of NMT reset node"
                time.sleep(0.01)

        reset_node()
        assert node.sdo[0x1016][1].raw == 0x1012C
        t0 = time.time()                  # the hub stamps frames with time.time()
        net.send_message(0x701, [0x05])
        end = time.monotonic() + 2.0
        while not [e for e in node.emcy.log if e.code == 0x8130]:
            assert time.monotonic() < end, "no EMCY 0x8130 within 2 s"
            time.sleep(0.01)
        err = next(e for e in node.emcy.log if e.code == 0x8130)
        assert err.timestamp - t0 >= 0.29      # not before the 300 ms timeout
        assert node.sdo[0x1001].raw & 0x10
        reset_node()
        assert node.sdo[0x1001].raw == 0
    finally:
        net.disconnect()


def test_realtime_run_reports_what_is_missing_and_completes(node_env, tmp_path):
    log, saved = tmp_path / "rt.log", tmp_path / "rt.npz"
    r = bench("run", "sine", "--duration", "1.0", "--pace", "realtime", "--no-plant",
              "--no-progress", "--log", str(log), "--save", str(saved), *node_env.flags,
              env=node_env.env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    err = r.stderr
    assert "node has no lockstep (0x2200 sub 1 missing): running in real time" in err
    assert "16384 counts/rev" in err and "EDS default" in err
    assert "0x2100" in err and "skipped" in err
    assert "1000 periods" in r.stdout
    tr = Trace.load(saved)
    node = tr.meta["node"]
    for index in OPTIONAL:   # every optional object the ECU uses is reported missing
        assert any(m.startswith(index) for m in node["missing"]), (index, node["missing"])
    assert node["encoder_counts_per_rev"] == 16384
    assert node["identity"]["product_code"] == 1
    assert "params" not in tr.meta          # the ECU does not know the node's parameters
    assert tr.meta["complete"] and len(tr) == 1000
    # real time: the trace is its log's rows (bench.bus.rows); a period whose TPDO reached
    # the ECU only after the next SYNC stays NaN, and each such row is counted. How many
    # are late is the machine's load, not the bench's (at most half was asserted here
    # until a CI run beside another job's tests had 820 of 1000 late)
    pos = tr["position_m"]
    missing = tr.meta["bus_rows"]["missing_frames"]["EMA_TPDO3"]
    assert int((~np.isfinite(pos)).sum()) == missing < len(tr)
    # the loop is closed through the node, exactly, whatever the load: every demand is the
    # controller's answer to what the ECU had, every TPDO set is the physics driven by
    # the demands the node had. How well the nut then follows the set-point is not
    # something real time guarantees on a shared machine (the ECU goes on stale TPDO sets
    # for bursts of periods: at load ~2 a run once had a median position error of 3.1
    # mm, against 0.105 mm in-process); lockstep does, and
    # test_lockstep_on_a_sync_driven_node_equals_in_process checks it period by period
    demand_err, sensor_err, n_rpdo = closed_loop_mismatch(log, make_profile("sine",
                                                                            duration_s=1.0))
    assert 0 < n_rpdo <= len(tr)
    assert demand_err == 0.0
    for name, err in sensor_err.items():
        assert err <= 1.001 * QUANT_TPDO[name], (name, err)
    ok = np.isfinite(pos)
    assert np.max(np.abs(pos[ok])) > 0.35e-3      # the nut moved (a 0.5 mm sine)
    # the log is complete: every SYNC, and the node's three TPDOs for each of them
    with can.LogReader(log) as reader:
        ids = Counter(m.arbitration_id for m in reader)
    assert ids[0x080] == 1000
    assert ids[0x190] == ids[0x290] == ids[0x390] == 1000
    dec = trace_from_log(log)
    assert len(dec) == 1000 and dec.meta["bad_frames"] == 0
    # of the parameters, only the SYNC period (read from 0x1006) is in the log
    assert dec.meta["params_from_sdo"] == ["sim.sync_period_s"]
    assert dec.meta["period_s"] == 1e-3 and dec.meta["counts_per_rev"] == 16384
    np.testing.assert_allclose(dec["setpoint_position_m"], tr["setpoint_position_m"],
                               rtol=0, atol=0.5e-8)


def test_set_without_parameter_objects_is_a_one_line_error_before_the_run(node_env, tmp_path):
    log = tmp_path / "set.log"
    r = bench("run", "sine", "--duration", "0.2", "--no-plant", "--no-progress",
              "--set", "effects.backlash_m=50e-6", "--log", str(log), *node_env.flags,
              env=node_env.env, timeout=60)
    line = one_line_error(r)
    assert "effects.backlash_m" in line and "0x2005 sub 1" in line
    assert not log.exists() or "080#" not in log.read_text()   # no SYNC: never started


def test_gap_excitation_load_needs_the_load_objects(node_env, tmp_path):
    r = bench("run", "gap-excitation", "--duration", "0.2", "--no-plant", "--no-progress",
              *node_env.flags, env=node_env.env, timeout=60)
    line = one_line_error(r)
    assert "load.kind" in line and "0x2006" in line and "--load-n 0" in line
    r = bench("run", "gap-excitation", "--duration", "0.2", "--load-n", "0", "--no-plant",
              "--no-progress", "--encoder-counts", "16384", *node_env.flags,
              env=node_env.env, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "200 periods" in r.stdout
    assert "16384 counts/rev from --encoder-counts" in r.stderr


def test_lockstep_is_refused_without_the_pace_object(node_env):
    r = bench("run", "sine", "--duration", "0.2", "--pace", "sync", "--no-plant",
              "--no-progress", *node_env.flags, env=node_env.env, timeout=60)
    line = one_line_error(r)
    assert "0x2200 sub 1" in line and "--pace realtime" in line


def test_lockstep_on_a_sync_driven_node_equals_in_process(node_env):
    """The caller vouches that the node steps one period per SYNC (the double does): the
    lockstep run is the in-process simulation within the DBC quantisation."""
    profile = make_profile("sine", duration_s=0.3)
    tr = run_over_bus(profile, pace="sync", settings=node_env.cfg, start_plant=False,
                      sync_driven=True)
    ref = simulate(profile, PlantParams())
    assert tr.meta["complete"] and len(tr) == len(ref)
    for col, q in QUANT.items():
        err = np.max(np.abs(tr[col] - ref[col]))
        assert err <= 20 * q, (col, err / q)
    np.testing.assert_allclose(tr["motor_angle_rad"], ref["motor_angle_rad"], rtol=0,
                               atol=2 * np.pi / 16384 * 20)
    assert tr.meta["pace"] == "sync"


def test_encoder_resolution_from_the_flag(node_env):
    """A node whose encoder has 4096 counts/rev and no 0x2003: the ECU takes the
    resolution from `encoder_counts` (--encoder-counts), and says where it came from."""
    child = start_minimal_node(node_env.cfg, node_env.state, "--node-id", "0x12",
                               "--set", "sensors.encoder_counts_per_rev=4096")
    try:
        profile = make_profile("sine", duration_s=0.2)
        said: list[str] = []
        tr = run_over_bus(profile, pace="sync", settings=node_env.cfg, start_plant=False,
                          sync_driven=True, node_id=0x12, encoder_counts=4096,
                          announce=said.append)
    finally:
        child.stop()
    ref = simulate(profile, PlantParams().with_dict({"sensors.encoder_counts_per_rev": 4096}))
    np.testing.assert_allclose(tr["motor_angle_rad"], ref["motor_angle_rad"], rtol=0,
                               atol=2 * np.pi / 4096 * 20)
    assert tr.meta["node"]["encoder_counts_per_rev"] == 4096
    assert "--encoder-counts" in tr.meta["node"]["encoder_counts_source"]
    assert any("4096 counts/rev" in s for s in said), said


def test_bad_encoder_flag_is_refused(node_env):
    with pytest.raises(BenchError, match="encoder-counts"):
        run_over_bus(make_profile("sine", duration_s=0.1), settings=node_env.cfg,
                     start_plant=False, encoder_counts=0)


def test_status_of_a_minimal_node(node_env):
    r = bench("status", *node_env.flags, env=node_env.env, timeout=60)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "node 0x10: PRE_OPERATIONAL" in out
    assert "product_code 0x1" in out
    assert "0x2100 (node_status)" in out and "0x2008 (sim)" in out
    assert "parameters: none read back" in out
