"""Synthetic frame sequences of a lockstep run as the ECU logs them, for the log-reader
tests (tests/unit/test_logs_*.py, tests/integration/test_logs_fuzz.py)."""

from __future__ import annotations

import can

from ema_contract.frames import Frames
from ema_contract.states import NMTCommand

F = Frames()
T0 = 1000.0
PERIOD = 1e-3


def at(msg: can.Message, ts: float) -> can.Message:
    msg.timestamp = round(ts, 6)
    return msg


def period(k: int, counter: int | None = None) -> list[can.Message]:
    """The frames of SYNC period k as the ECU logs them (values change with k)."""
    t = T0 + k * PERIOD
    c = (k % 240) + 1 if counter is None else counter
    return [
        at(F.encode("SYNC", {"SYNC_Counter": c}), t),
        at(F.encode("ECU_Setpoint", {"SetpointPosition": 1e-6 * k, "SetpointSpeed": 0.0,
                                      "Mode": 1}), t + 50e-6),
        at(F.encode("EMA_TPDO1", {"MotorCurrent": 0.01 * k, "StatusWord": 0x40}), t + 100e-6),
        at(F.encode("EMA_TPDO2", {"EncoderAngle": 3 * k, "EncoderSpeed": 0.1 * k}),
            t + 110e-6),
        at(F.encode("EMA_TPDO3", {"LvdtPosition": 1e-6 * k, "WindingTemperature": 300.0,
                                   "LoadForce": 2.0 * k}), t + 120e-6),
        at(F.encode("EMA_RPDO1", {"CurrentDemand": 0.02 * k, "ControlWord": 1}), t + 300e-6),
    ]


def run(n: int = 20) -> list[can.Message]:
    """NMT start, then n SYNC periods."""
    start = at(F.encode("NMT", {"NMT_Command": int(NMTCommand.START), "NMT_NodeId": 0x10}),
                T0 - PERIOD)
    out = [start]
    for k in range(n):
        out += period(k)
    return out


def where(seq: list[can.Message], k: int, name: str) -> int:
    """Index in `seq` of frame `name` of period k."""
    cob = F.cob[name]
    ts = T0 + k * PERIOD
    for i, m in enumerate(seq):
        if m.arbitration_id == cob and ts - 1e-9 <= m.timestamp < ts + PERIOD - 1e-9:
            return i
    raise AssertionError(f"no {name} in period {k}")


def clone(m: can.Message) -> can.Message:
    return can.Message(timestamp=m.timestamp, arbitration_id=m.arbitration_id,
                       is_extended_id=m.is_extended_id, data=bytes(m.data), is_rx=m.is_rx)


def write_log(path, msgs) -> None:
    with can.CanutilsLogWriter(path) as w:
        for m in msgs:
            w.on_message_received(m)
