"""What crosses the bus: the DBC and the EDS shipped in `ema_contract/dbc/` (the only
place frame layouts live), bound to the node ids in use.

`Frames` binds the DBC (`ema.dbc`, cantools, strict) to the node ids in use and
encodes/decodes frames by message and signal name; `load_od` imports the EDS (`ema.eds`,
canopen) for a node id. Both the plant node and the ECU use these, so neither side holds
a frame layout of its own. The enumerations (NMT, control and status words) are in
`ema_contract.states`; the EDS's plant parameter objects in `plant_rt.paramobjects`.

The files are package data; `$EMA_BENCH_DBC_DIR` points at another directory holding
`ema.dbc` and `ema.eds` (a real actuator's description).
"""

from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path
from typing import Any

import can
import cantools

DBC_DIR_ENV = "EMA_BENCH_DBC_DIR"
PACKAGE_DBC_DIR = Path(__file__).resolve().parent / "dbc"   # ema.dbc, ema.eds (package data)


class FrameError(ValueError):
    """A frame with a known id that does not decode (wrong length)."""


def dbc_dir() -> Path:
    """Directory holding ema.dbc and ema.eds ($EMA_BENCH_DBC_DIR, else the package's)."""
    env = os.environ.get(DBC_DIR_ENV)
    return Path(env) if env else PACKAGE_DBC_DIR


def dbc_path() -> Path:
    return dbc_dir() / "ema.dbc"


def eds_path() -> Path:
    return dbc_dir() / "ema.eds"


@lru_cache(maxsize=4)
def _load_db(path: str) -> cantools.database.can.Database:
    db = cantools.database.load_file(path, strict=True)
    if not isinstance(db, cantools.database.can.Database):
        raise TypeError(f"{path} is not a CAN database")
    return db


def load_db() -> cantools.database.can.Database:
    """The DBC, loaded strictly (cached)."""
    path = dbc_path()
    if not path.exists():
        raise FileNotFoundError(f"bus description not found: {path} (set {DBC_DIR_ENV})")
    return _load_db(str(path))


def load_od(node_id: int | None = None):
    """The actuator's object dictionary from the EDS, COB-IDs resolved for `node_id`."""
    import canopen
    path = eds_path()
    if not path.exists():
        raise FileNotFoundError(f"object dictionary not found: {path} (set {DBC_DIR_ENV})")
    return canopen.import_od(str(path), node_id if node_id is not None else default_ids()[0])


def default_ids() -> tuple[int, int]:
    """(actuator node id, ECU node id) from the DBC attribute NmStationAddress."""
    db = load_db()
    ids = {n.name: int(n.dbc.attributes["NmStationAddress"].value) for n in db.nodes}
    return ids["EMA"], ids["ECU"]


class Frames:
    """The DBC's messages bound to the node ids in use.

    Frame ids of node-specific messages (PDOs, EMCY, heartbeat) follow CANopen's
    predefined connection set: id = function code + node id. The DBC is written for the
    default ids (NmStationAddress); other ids shift those messages accordingly.
    """

    def __init__(self, node_id: int | None = None, ecu_id: int | None = None) -> None:
        self.db = load_db()
        d_node, d_ecu = default_ids()
        self.node_id = d_node if node_id is None else int(node_id)
        self.ecu_id = d_ecu if ecu_id is None else int(ecu_id)
        for nid in (self.node_id, self.ecu_id):
            if not 1 <= nid <= 127:
                raise ValueError(f"CANopen node id must be 1..127, got {nid}")
        if self.node_id == self.ecu_id:
            raise ValueError("the actuator and the ECU need different node ids")
        self.by_name: dict[str, cantools.database.can.Message] = {}
        self.cob: dict[str, int] = {}
        self.by_cob: dict[int, cantools.database.can.Message] = {}
        for m in self.db.messages:
            fid = m.frame_id
            if fid >= 0x80 and (fid & 0x7F) == d_node:
                cob = fid - d_node + self.node_id
            elif fid >= 0x80 and (fid & 0x7F) == d_ecu:
                cob = fid - d_ecu + self.ecu_id
            else:
                cob = fid
            self.by_name[m.name] = m
            self.cob[m.name] = cob
            self.by_cob[cob] = m
        self.sdo_rx = 0x600 + self.node_id   # client -> server (CiA 301 default)
        self.sdo_tx = 0x580 + self.node_id

    # -- encoding -----------------------------------------------------------------------
    def encode(self, name: str, values: dict[str, Any]) -> can.Message:
        """A frame of message `name` (strict: every signal given and within its range)."""
        m = self.by_name[name]
        data = m.encode(values, strict=True)
        return can.Message(arbitration_id=self.cob[name], data=data, is_extended_id=False)

    def encode_unchecked(self, name: str, values: dict[str, Any]) -> can.Message:
        """As `encode` without range checks (tests that send bad values on purpose)."""
        m = self.by_name[name]
        return can.Message(arbitration_id=self.cob[name], data=m.encode(values, strict=False),
                           is_extended_id=False)

    def clamp(self, name: str, signal: str, value: float) -> float:
        """`value` limited to the signal's DBC range (non-finite -> 0)."""
        s = self.by_name[name].get_signal_by_name(signal)
        if not math.isfinite(value):
            return 0.0
        lo, hi = s.minimum, s.maximum
        if lo is not None and value < lo:
            return float(lo)
        if hi is not None and value > hi:
            return float(hi)
        return value

    # -- decoding -----------------------------------------------------------------------
    def message(self, can_id: int) -> cantools.database.can.Message | None:
        return self.by_cob.get(can_id)

    def decode(self, msg: can.Message, allow_truncated: bool = False
               ) -> tuple[str, dict[str, Any]] | None:
        """(message name, signals) of a frame, None for an id the DBC does not describe.

        Raises FrameError for a described id with the wrong length. `allow_truncated`
        (reading logs): a shorter frame gives the signals that fit whole in it (none:
        FrameError), as a frame of an older layout whose later signals were appended
        since (EMA_TPDO3 before the load cell)."""
        m = self.by_cob.get(msg.arbitration_id)
        if m is None or msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            return None
        short = allow_truncated and 0 < len(msg.data) < m.length
        sig = None
        if len(msg.data) == m.length or short:
            sig = m.decode_simple(bytes(msg.data), decode_choices=False, scaling=True,
                                  allow_truncated=short)
        if sig is None or (short and not sig):   # wrong length, or no signal fits
            raise FrameError(f"{m.name} (0x{msg.arbitration_id:03X}) with {len(msg.data)} "
                             f"bytes, expected {m.length}")
        return m.name, sig

    # -- value tables -------------------------------------------------------------------
    def choice(self, name: str, signal: str, label: str) -> int:
        """The numeric value of `label` in the signal's value table."""
        s = self.by_name[name].get_signal_by_name(signal)
        for value, text in (s.choices or {}).items():
            if str(text) == label:
                return int(value)
        raise KeyError(f"{name}.{signal} has no value {label!r}")

    def label(self, name: str, signal: str, value: int) -> str:
        s = self.by_name[name].get_signal_by_name(signal)
        text = s.choices.get(int(value)) if s.choices else None
        return str(text) if text is not None else f"0x{int(value):04X}"

    def cycle_time_ms(self, name: str) -> int:
        return int(self.by_name[name].cycle_time or 0)


def exclude_filters(ids: list[int]) -> list[dict[str, int]]:
    """python-can acceptance filters passing every 11-bit id except `ids`.

    One filter per bit: "bit i differs from the excluded id's bit i"; their union
    is everything but the id (one id supported, the common case: drop a busy frame
    this node has no use for)."""
    if not ids:
        return []
    if len(ids) > 1:
        raise ValueError("exclude_filters supports one id")
    x = ids[0]
    return [{"can_id": (~x) & (1 << i), "can_mask": 1 << i} for i in range(11)]
