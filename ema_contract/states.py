"""The bus's enumerations: CANopen's (CiA 301) and the actuator's status/control bits.

`Status` holds the plant's own status bits (the low nibble of the status word), which
`plant_rt.model.Plant.status` computes; `StatusWord` is the whole TPDO1 StatusWord: the
plant's bits, then the node's own. A unit test checks these against the DBC's value
tables and comments (`dbc/ema.dbc`).
"""

from __future__ import annotations

from enum import IntEnum, IntFlag


class Status(IntFlag):
    """Plant status bits (published in the status word)."""
    NONE = 0
    OVERCURRENT = 1       # the drive held the current at its limit in the last period
    END_OF_STROKE = 2     # |nut position| beyond screw.travel_limit_m
    OVERTEMPERATURE = 4   # winding temperature above plant_rt.model.OVERTEMPERATURE_K
    FAULT = 8             # non-finite state: the plant stopped integrating


class NMTState(IntEnum):
    """CANopen NMT states as sent in the heartbeat (CiA 301)."""
    BOOT_UP = 0
    STOPPED = 4
    OPERATIONAL = 5
    PRE_OPERATIONAL = 127


class NMTCommand(IntEnum):
    """NMT module-control command specifiers (CiA 301)."""
    START = 1
    STOP = 2
    ENTER_PRE_OPERATIONAL = 128
    RESET_NODE = 129
    RESET_COMMUNICATION = 130


class ControlWord(IntFlag):
    """RPDO1 ControlWord bits (dbc/ema.dbc, EMA_RPDO1)."""
    NONE = 0
    ENABLE = 0x1
    FAULT_RESET = 0x80


class StatusWord(IntFlag):
    """TPDO1 StatusWord bits (dbc/ema.dbc, EMA_TPDO1): the plant's `Status`
    bits, then the node's own."""
    NONE = 0
    OVERCURRENT = int(Status.OVERCURRENT)
    END_OF_STROKE = int(Status.END_OF_STROKE)
    OVERTEMPERATURE = int(Status.OVERTEMPERATURE)
    PLANT_FAULT = int(Status.FAULT)
    COMMAND_TIMEOUT = 0x10
    DEMAND_CLAMPED = 0x20
    ENABLED = 0x40
    RPDO_MISSING = 0x80
    DEADLINE_MISS = 0x100


class Pace(IntEnum):
    """Plant pacer (object 0x2200 sub 1)."""
    REALTIME = 0
    SYNC = 1
