"""The plant node on an in-process virtual bus: NMT, SDO parameters and aborts, lockstep
PDOs, bad frames, EMCY and the heartbeat consumer (canopen's test_local.py shape: the
node and a plain canopen RemoteNode on one bus)."""

from __future__ import annotations

import math
import threading
import time
import uuid

import can
import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.frames import Frames, load_od
from ema_contract.states import NMTCommand, NMTState, Pace, StatusWord
from plant_rt.model import Plant
from plant_rt.node import PlantNode
from plant_rt.params import PlantParams


class Rig:
    def __init__(self, params: PlantParams | None = None) -> None:
        chan = f"t-{uuid.uuid4().hex}"
        self.nbus = can.Bus(interface="virtual", channel=chan)
        self.node = PlantNode(self.nbus, params or PlantParams(), pace=Pace.SYNC)
        self.frames = Frames()
        self.bus = can.Bus(interface="virtual", channel=chan)
        self.rx: list[can.Message] = []
        self.net = canopen.Network(self.bus)
        self.remote = canopen.RemoteNode(0x10, load_od())
        self.net.add_node(self.remote)
        self.remote.sdo.RESPONSE_TIMEOUT = 1.0
        self.net.notifier = can.Notifier(self.bus, [*self.net.listeners, self._collect],
                                         timeout=0.02)
        self.th = threading.Thread(target=self.node.run, daemon=True)
        self.th.start()
        self.wait_for(lambda m: m.arbitration_id == 0x710 and m.data[0] == 0)

    def _collect(self, msg: can.Message) -> None:
        self.rx.append(msg)

    def send(self, name: str, values: dict, strict: bool = True) -> None:
        msg = (self.frames.encode if strict else self.frames.encode_unchecked)(name, values)
        self.bus.send(msg)

    def raw(self, can_id: int, data: bytes) -> None:
        self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

    def wait_for(self, pred, timeout: float = 3.0) -> can.Message:
        end = time.monotonic() + timeout
        seen = 0
        while time.monotonic() < end:
            for m in self.rx[seen:]:
                if pred(m):
                    return m
            seen = len(self.rx)
            time.sleep(0.002)
        raise AssertionError("expected frame not seen")

    def nmt(self, cmd: NMTCommand) -> None:
        self.send("NMT", {"NMT_Command": int(cmd), "NMT_NodeId": 0x10})
        time.sleep(0.05)

    def sync(self, counter: int) -> list[dict]:
        """SYNC and the three TPDOs it answers with (decoded)."""
        start = len(self.rx)
        self.send("SYNC", {"SYNC_Counter": counter})
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            tp = [m for m in self.rx[start:] if m.arbitration_id in (0x190, 0x290, 0x390)]
            if len(tp) == 3:
                return [self.frames.decode(m)[1] for m in tp]
            time.sleep(0.001)
        raise AssertionError("no TPDOs")

    def status(self, name: str):
        return self.remote.sdo["node_status"][name].raw

    def emcy_names(self) -> list[str]:
        return [self.frames.label("EMA_EMCY", "EMCY_ErrorCode", self.frames.decode(m)[1][
            "EMCY_ErrorCode"]) for m in self.rx if m.arbitration_id == 0x90]

    def close(self) -> None:
        self.node.stop()
        self.th.join(2.0)
        self.net.notifier.stop(1.0)
        self.bus.shutdown()
        self.nbus.shutdown()


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.close()


def test_boot_heartbeat_and_nmt_states(rig):
    hb = rig.wait_for(lambda m: m.arbitration_id == 0x710 and m.data[0] == 127, timeout=1.0)
    assert hb.data[0] == NMTState.PRE_OPERATIONAL
    rig.nmt(NMTCommand.START)
    assert rig.status("nmt_state") == NMTState.OPERATIONAL
    rig.nmt(NMTCommand.STOP)
    assert rig.node.state == NMTState.STOPPED
    rig.nmt(NMTCommand.ENTER_PRE_OPERATIONAL)
    assert rig.status("nmt_state") == NMTState.PRE_OPERATIONAL


def test_sdo_parameters_read_write_and_aborts(rig):
    sdo = rig.remote.sdo
    assert sdo["motor"]["resistance_ohm"].raw == 0.4
    assert sdo["drive"]["pwm_mode"].raw == 0
    assert sdo["sensors"]["noise"].raw is False
    assert sdo["sensors"]["encoder_counts_per_rev"].raw == 16384
    assert math.isnan(sdo["screw"]["reaction_lever_m"].raw)
    sdo["effects"]["backlash_m"].raw = 5e-5
    sdo["drive"]["pwm_mode"].raw = 1
    sdo["sensors"]["noise"].raw = True
    assert rig.node.params.effects.backlash_m == 5e-5
    assert rig.node.params.drive.pwm_mode == "averaged"
    assert rig.node.params.sensors.noise is True
    for var, value, code in (("resistance_ohm", 1e6, 0x06090031),
                             ("resistance_ohm", 0.0, 0x06090032)):
        with pytest.raises(SdoAbortedError) as e:
            sdo["motor"][var].raw = value
        assert e.value.code == code
    with pytest.raises(SdoAbortedError) as e:
        sdo["drive"]["pwm_mode"].raw = 7
    assert e.value.code == 0x06090030
    with pytest.raises(SdoAbortedError) as e:
        sdo.upload(0x2F00, 0)
    assert e.value.code == 0x06020000
    with pytest.raises(SdoAbortedError) as e:
        sdo.upload(0x2000, 0x7F)
    assert e.value.code == 0x06090011
    with pytest.raises(SdoAbortedError) as e:
        sdo["node_status"]["cycles"].raw = 3
    assert e.value.code == 0x06010002
    rig.nmt(NMTCommand.START)
    with pytest.raises(SdoAbortedError) as e:
        sdo["motor"]["resistance_ohm"].raw = 0.5
    assert e.value.code == 0x08000022
    assert rig.node.params.motor.resistance_ohm == 0.4
    # reset node: parameters back to their start-up values, boot-up again
    rig.nmt(NMTCommand.RESET_NODE)
    assert sdo["effects"]["backlash_m"].raw == 0.0
    assert rig.node.state == NMTState.PRE_OPERATIONAL


def test_lockstep_pdos_follow_the_plant_and_apply_the_rpdo_at_the_next_sync(rig):
    ref = Plant(PlantParams())
    rig.nmt(NMTCommand.START)
    demands = [0.0, 3.0, 3.0, -2.0, 1.0]
    applied = 0.0
    for k, d in enumerate(demands, start=1):
        tp = rig.sync(k)
        m = ref.measure()
        assert tp[0]["MotorCurrent"] == pytest.approx(m.current_a, abs=5e-5)
        assert tp[1]["EncoderSpeed"] == pytest.approx(m.motor_speed_rad_s, abs=5e-5)
        assert tp[2]["LvdtPosition"] == pytest.approx(m.position_m, abs=5e-9)
        assert tp[0]["StatusWord"] & StatusWord.ENABLED or k == 1
        rig.send("EMA_RPDO1", {"CurrentDemand": d, "ControlWord": 1})
        ref.step(applied)   # the demand of the previous period
        applied = d
    assert rig.status("cycles") == len(demands)
    assert rig.status("rpdo_missing") == 0
    assert rig.status("plant_time_s") == pytest.approx(len(demands) * 1e-3)


def test_bad_frames_are_counted_and_ignored(rig):
    rig.nmt(NMTCommand.START)
    rig.sync(1)
    rig.raw(0x210, b"\x00\x00")                        # RPDO with wrong DLC
    rig.raw(0x123, b"\x01\x02\x03")                    # unknown id
    rig.raw(0x7FF, b"")                                # unknown id
    rig.raw(0x080, b"\x01\x02\x03")                    # SYNC with wrong DLC
    rig.send("EMA_RPDO1", {"CurrentDemand": float("nan"), "ControlWord": 1}, strict=False)
    rig.sync(2)
    rig.send("EMA_RPDO1", {"CurrentDemand": 900.0, "ControlWord": 1})   # beyond 25 A
    tp = rig.sync(3)
    assert tp[0]["StatusWord"] & StatusWord.DEMAND_CLAMPED
    assert rig.node.applied_a == pytest.approx(25.0)
    rig.send("EMA_RPDO1", {"CurrentDemand": 1.0, "ControlWord": 1})
    rig.sync(4)
    rig.sync(6)                                        # counter jump: a lost SYNC
    assert rig.status("bad_frames") == 2
    assert rig.status("unknown_frames") == 2
    assert rig.status("demands_invalid") == 2
    assert rig.status("sync_counter_gaps") == 1
    assert rig.status("rpdo_missing") == 1
    # demand_invalid rose 1 SYNC period after pdo_length: it waits for the end of the EMCY
    # inhibit time (0x1015, 100 ms; SYNC periods in lockstep)
    assert rig.emcy_names() == ["pdo_length"]
    for k in range(7, 7 + 100):
        rig.sync(k)
    assert rig.emcy_names()[:2] == ["pdo_length", "demand_invalid"]
    assert rig.status("emcy_suppressed") == 0
    assert rig.node.state == NMTState.OPERATIONAL


def test_ecu_heartbeat_lost_forces_zero_demand_and_sends_emcy(rig):
    """Lockstep: the consumer (0x1016, 300 ms) counts SYNC periods, not wall time; on a
    timeout the error behaviour 0x1029 = 0 takes the node out of OPERATIONAL."""
    rig.nmt(NMTCommand.START)
    rig.send("ECU_Heartbeat", {"ECU_NMTState": 5})
    rig.send("EMA_RPDO1", {"CurrentDemand": 4.0, "ControlWord": 1})
    rig.sync(1)
    assert rig.node.applied_a == 4.0
    time.sleep(0.4)                                   # wall time does not count in lockstep
    for k in range(2, 301):
        tp = rig.sync((k - 1) % 240 + 1)
        assert not tp[0]["StatusWord"] & StatusWord.COMMAND_TIMEOUT
    assert rig.emcy_names() == [] and rig.node.applied_a == 4.0
    rig.send("SYNC", {"SYNC_Counter": 301 % 240})     # 301 SYNC periods without heartbeat
    em = rig.wait_for(lambda m: m.arbitration_id == 0x90, timeout=1.0)
    assert rig.emcy_names() == ["heartbeat_lost"]
    word = rig.frames.decode(em)[1]["EMCY_StatusWord"]
    assert word & StatusWord.COMMAND_TIMEOUT and not word & StatusWord.ENABLED
    assert rig.status("nmt_state") == NMTState.PRE_OPERATIONAL
    assert rig.status("heartbeat_timeouts") == 1
    assert rig.status("applied_demand_a") == 0.0
    # the ECU comes back, starts the node and resets the fault: commands apply again
    rig.send("ECU_Heartbeat", {"ECU_NMTState": 5})
    rig.nmt(NMTCommand.START)
    rig.send("EMA_RPDO1", {"CurrentDemand": 2.0, "ControlWord": 0x81})
    tp = rig.sync(62)
    assert not tp[0]["StatusWord"] & StatusWord.COMMAND_TIMEOUT
    assert rig.node.applied_a == 2.0


def test_control_objects(rig):
    sdo = rig.remote.sdo
    assert sdo["node_control"]["pace"].raw == Pace.SYNC
    sdo["node_control"]["pace"].raw = 0
    assert rig.node.pace == Pace.REALTIME
    sdo["node_control"]["pace"].raw = 1
    with pytest.raises(SdoAbortedError):
        sdo["node_control"]["pace"].raw = 9
    sdo[0x1006].raw = 2000                         # SYNC period 2 ms
    assert rig.node.params.sim.sync_period_s == pytest.approx(2e-3)
    assert sdo["sim"]["sync_period_s"].raw == pytest.approx(2e-3)
    sdo["node_control"]["reset_plant"].raw = 1
    sdo["node_control"]["reset_counters"].raw = 1
    assert sdo["node_status"]["frames_received"].raw < 5


def test_a_new_node_has_its_compiled_step_loaded_before_it_boots():
    """Compiling or loading the plant's step (numba) takes seconds on a cold cache; a
    node doing it at its first SYNC misses its heartbeat and the ECU declares it lost. A
    fresh process that only builds a node has the step and the sensors loaded."""
    import subprocess
    import sys
    code = ("import can\n"
            "from plant_rt import kernel as K\n"
            "from plant_rt.node import PlantNode\n"
            "bus = can.Bus(interface='virtual', channel='warm-check')\n"
            "PlantNode(bus)\n"
            "bus.shutdown()\n"
            "print(len(K.advance.signatures), len(K.measure.signatures))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True)
    assert out.stdout.split() == ["1", "1"], out.stdout + out.stderr
