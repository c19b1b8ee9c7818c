"""The ECU's period steps in real time when the first TPDO set is late (a loaded machine):
the fault reset goes with the first RPDO actually sent, and a pre-run command timeout is
tolerated exactly until a status word answers a SYNC after that reset. The ECU runs on
python-can's in-process virtual bus; a second virtual bus plays the plant's frames."""

from __future__ import annotations

import itertools

import can
import pytest

from bench.ecu.errors import PlantFault
from bench.ecu.master import Ecu
from bench.ecu.period import EcuStats, PeriodSteps
from bench.profiles.catalog import make_profile
from bench.sim.control import ControllerParams
from ema_contract.states import ControlWord, Pace, StatusWord
from plant_rt.params import PlantParams

PARAMS = PlantParams()

TIMEOUT = int(StatusWord.COMMAND_TIMEOUT)
_channels = itertools.count()


@pytest.fixture
def rig():
    channel = f"ecu-period-{next(_channels)}"
    ecu_bus = can.Bus(interface="virtual", channel=channel)
    plant_bus = can.Bus(interface="virtual", channel=channel)
    ecu = Ecu(ecu_bus)
    yield ecu, plant_bus
    ecu_bus.shutdown()
    plant_bus.shutdown()


def _steps(ecu: Ecu, pace: Pace) -> PeriodSteps:
    ts = PARAMS.sim.sync_period_s
    steps = PeriodSteps(ecu, make_profile("sine", duration_s=0.05), PARAMS,
                        ControllerParams(sample_period_s=ts), pace, 50, 0, None, EcuStats())
    steps.setup(False)
    return steps


def _answer(ecu: Ecu, plant_bus: can.BusABC, steps: PeriodSteps, status: int) -> None:
    """The plant's TPDO1-3 of one SYNC, received by the ECU's period steps."""
    f = ecu.frames
    plant_bus.send(f.encode("EMA_TPDO1", {"MotorCurrent": 0.0, "StatusWord": status}))
    plant_bus.send(f.encode("EMA_TPDO2", {"EncoderAngle": 0, "EncoderSpeed": 0.0}))
    plant_bus.send(f.encode("EMA_TPDO3", {"LvdtPosition": 0.0, "WindingTemperature": 300.0,
                                          "LoadForce": 0.0}))
    for _ in range(3):
        steps.poll(1.0)


def _controls(ecu: Ecu, plant_bus: can.BusABC) -> list[int]:
    """The control words of the RPDO1s the ECU sent (read off the bus, decoded)."""
    words = []
    while (msg := plant_bus.recv(0.0)) is not None:
        if msg.arbitration_id == ecu.frames.cob["EMA_RPDO1"]:
            words.append(int(ecu.frames.decode(msg)[1]["ControlWord"]))
    return words


def _late_start(rig) -> PeriodSteps:
    """Real time, a timeout latched before the run: SYNC 0-2 answered after their
    windows (no RPDO in periods 0-2), their sets in by period 3, the first demand."""
    ecu, plant_bus = rig
    steps = _steps(ecu, Pace.REALTIME)
    for _ in range(3):
        _answer(ecu, plant_bus, steps, TIMEOUT)
    steps.control(3)
    return steps


def test_real_time_first_rpdo_sent_late_carries_the_fault_reset(rig):
    ecu, plant_bus = rig
    steps = _late_start(rig)
    steps.control(4)
    words = _controls(ecu, plant_bus)
    assert words == [int(ControlWord.ENABLE | ControlWord.FAULT_RESET),
                     int(ControlWord.ENABLE)]


def test_pre_run_timeout_tolerated_until_a_word_answers_a_sync_after_the_reset(rig):
    ecu, plant_bus = rig
    steps = _late_start(rig)         # fault reset sent with the demand of period 3
    _answer(ecu, plant_bus, steps, TIMEOUT)     # the answer to SYNC 3: before the reset
    steps.control(4)
    _answer(ecu, plant_bus, steps, TIMEOUT)     # SYNC 4: after the reset, still latched
    with pytest.raises(PlantFault, match="command timeout"):
        steps.control(5)


def test_pre_run_timeout_cleared_by_the_reset_passes(rig):
    ecu, plant_bus = rig
    steps = _late_start(rig)
    for k in range(4, 30):
        _answer(ecu, plant_bus, steps, TIMEOUT if k == 4 else 0)
        steps.control(k)
    assert steps.stats.periods == 30


def test_lockstep_timeout_tolerated_at_sync_0_only(rig):
    ecu, plant_bus = rig
    steps = _steps(ecu, Pace.SYNC)
    _answer(ecu, plant_bus, steps, TIMEOUT)
    steps.control(0)
    _answer(ecu, plant_bus, steps, TIMEOUT)
    with pytest.raises(PlantFault, match="SYNC 1"):
        steps.control(1)


def test_other_failing_bits_are_never_tolerated(rig):
    ecu, plant_bus = rig
    steps = _steps(ecu, Pace.REALTIME)
    _answer(ecu, plant_bus, steps, TIMEOUT | int(StatusWord.DEMAND_CLAMPED))
    with pytest.raises(PlantFault, match="SYNC 0"):
        steps.control(0)


def test_real_time_heartbeat_kept_while_waiting_for_the_first_tpdo_set(rig):
    ecu, plant_bus = rig
    steps = _steps(ecu, Pace.REALTIME)
    steps.pacer.start(0.0)
    steps.wait_first(0)
    cobs = []
    while (msg := plant_bus.recv(0.0)) is not None:
        cobs.append(msg.arbitration_id)
    assert cobs == [ecu.frames.cob["ECU_Heartbeat"]]
