"""What crosses the bus: the DBC and the EDS of the top-level `dbc/` (the only place
frame layouts live), bound to the node ids in use.

`Frames` binds the DBC (`ema.dbc`, cantools, strict) to the node ids in use and
encodes/decodes frames by message and signal name; `load_od` imports the EDS (`ema.eds`,
canopen) for a node id. Both the plant node and the ECU use these, so neither side holds
a frame layout of its own. The enumerations (NMT, control and status words) are in
`ema_contract.states`; the EDS's plant parameter objects in `plant_rt.paramobjects`.

The files' source is the repository's `dbc/`; the wheel carries them as package data in
`ema_contract/dbc/` (setup.py's build step), found with importlib.resources, and a
checkout (an editable install, or PYTHONPATH) reads `dbc/` next to the package.
`$EMA_BENCH_DBC_DIR` points at another directory holding `ema.dbc` and `ema.eds` (a real
actuator's description).
"""

from __future__ import annotations

import math
import os
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import can
import cantools
import numpy as np

DBC_DIR_ENV = "EMA_BENCH_DBC_DIR"


def _shipped_dbc_dir() -> Path:
    """ema.dbc and ema.eds as shipped: the package's copy in an installed wheel, else the
    checkout's top-level dbc/ (next to the package: an editable install or PYTHONPATH)."""
    packaged = Path(str(resources.files("ema_contract") / "dbc"))
    if (packaged / "ema.dbc").is_file():
        return packaged
    return Path(__file__).resolve().parents[1] / "dbc"


SHIPPED_DBC_DIR = _shipped_dbc_dir()


class FrameError(ValueError):
    """A frame with a known id that does not decode (wrong length)."""


def dbc_dir() -> Path:
    """Directory holding ema.dbc and ema.eds ($EMA_BENCH_DBC_DIR, else the shipped pair)."""
    env = os.environ.get(DBC_DIR_ENV)
    return Path(env) if env else SHIPPED_DBC_DIR


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
        self._codecs: dict[str, PayloadCodec | None] = {}

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
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            return None
        return self.decode_payload(msg.arbitration_id, bytes(msg.data), allow_truncated)

    def decode_payload(self, can_id: int, data: bytes, allow_truncated: bool = False
                       ) -> tuple[str, dict[str, Any]] | None:
        """`decode` of a data frame with an 11-bit id given as its id and payload."""
        m = self.by_cob.get(can_id)
        if m is None:
            return None
        short = allow_truncated and 0 < len(data) < m.length
        sig = None
        if len(data) == m.length or short:
            sig = m.decode_simple(data, decode_choices=False, scaling=True,
                                  allow_truncated=short)
        if sig is None or (short and not sig):   # wrong length, or no signal fits
            raise FrameError(f"{m.name} (0x{can_id:03X}) with {len(data)} "
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

    # -- many frames at once ------------------------------------------------------------
    def codec(self, name: str) -> PayloadCodec | None:
        """The vectorised codec of message `name` (`PayloadCodec`), None for a message it
        does not handle (multiplexed, a container, over 8 bytes): use `decode`/`encode`."""
        if name not in self._codecs:
            m = self.by_name[name]
            self._codecs[name] = PayloadCodec(m) if PayloadCodec.handles(m) else None
        return self._codecs[name]


class PayloadCodec:
    """One DBC message's signals decoded from (and encoded into) many payloads at once with
    numpy, from the DBC's own signal specs (start bit, length, byte order, sign, IEEE
    float, scale, offset): the same arithmetic cantools does for one payload
    (`decode_simple(decode_choices=False, scaling=True)`, `encode(strict=False)`), to the
    bit (tests/unit/test_fast_decode.py compares them). For messages of up to 8 bytes,
    neither multiplexed nor containers (`handles`)."""

    def __init__(self, msg: cantools.database.can.Message) -> None:
        if not self.handles(msg):
            raise ValueError(f"{msg.name}: no vectorised codec (multiplexed, container or "
                             f"over 8 bytes)")
        self.name, self.length = msg.name, msg.length
        self.signals = [_SignalSpec(s) for s in msg.signals]
        self.names = tuple(s.name for s in self.signals)

    @staticmethod
    def handles(msg: cantools.database.can.Message) -> bool:
        return (not msg.is_multiplexed() and not msg.is_container and msg.length <= 8
                and all(not s.conversion.is_float or s.length in (16, 32, 64)
                        for s in msg.signals))

    def fits(self, n_bytes: int) -> tuple[str, ...]:
        """The signals whole in a payload of `n_bytes` (cantools' rule for a truncated
        frame: the signal's bits, numbered in transmission order, all within it)."""
        return tuple(s.name for s in self.signals if s.seq_start + s.length <= 8 * n_bytes)

    def decode(self, payloads: np.ndarray, lengths: np.ndarray | None = None
               ) -> dict[str, np.ndarray]:
        """Signal name -> float64 values of `payloads` (uint8, shape (n, length); bytes
        past a frame's end of any value), NaN where the frame's length (`lengths`, default
        all whole) does not hold the signal whole (0: no frame)."""
        words = self._words(payloads)
        out: dict[str, np.ndarray] = {}
        for s in self.signals:
            v = s.scaled(words[s.byte_order])
            if lengths is not None:
                v[s.seq_start + s.length > 8 * lengths.astype(np.int64)] = np.nan
            out[s.name] = v
        return out

    def encode(self, values: dict[str, np.ndarray]) -> np.ndarray:
        """The payloads (uint8, shape (n, length)) of per-frame signal values (every
        signal given, as `encode(strict=False)` would take them: no range check)."""
        n = len(next(iter(values.values()))) if values else 0
        words = {"little_endian": np.zeros(n, np.uint64), "big_endian": np.zeros(n, np.uint64)}
        for s in self.signals:
            words[s.byte_order] |= s.packed(np.asarray(values[s.name]))
        raw = (words["little_endian"].astype("<u8").view(np.uint8).reshape(n, 8)
               | words["big_endian"].astype(">u8").view(np.uint8).reshape(n, 8))
        return raw[:, :self.length]

    def _words(self, payloads: np.ndarray) -> dict[str, np.ndarray]:
        p = np.asarray(payloads, dtype=np.uint8).reshape(-1, self.length)
        full = np.zeros((len(p), 8), np.uint8)
        full[:, :self.length] = p
        return {"little_endian": full.view("<u8")[:, 0].astype(np.uint64),
                "big_endian": full.view(">u8")[:, 0].astype(np.uint64)}


class _SignalSpec:
    """One signal's place and scaling, from its DBC spec (see `PayloadCodec`)."""

    def __init__(self, s: Any) -> None:
        self.name, self.length, self.byte_order = s.name, s.length, s.byte_order
        self.signed, self.is_float = bool(s.is_signed), bool(s.conversion.is_float)
        if s.byte_order == "little_endian":
            self.seq_start = s.start
            self.shift = s.start                              # from the little-endian LSB
        else:   # cantools' sawtooth -> sequential bit number of the MSB
            self.seq_start = 8 * (s.start // 8) + (7 - s.start % 8)
            self.shift = 64 - self.seq_start - self.length    # of the big-endian 64-bit word
        self.mask = (1 << self.length) - 1
        conv = s.conversion
        self.scale, self.offset = getattr(conv, "scale", 1), getattr(conv, "offset", 0)
        ints = (isinstance(self.scale, int) and isinstance(self.offset, int)
                and not self.is_float)
        self.int_math = ints and self.length + abs(self.scale).bit_length() < 62 \
            and abs(self.offset) < 2 ** 61
        self.object_math = ints and not self.int_math         # exact Python ints

    def raw(self, word: np.ndarray) -> np.ndarray:
        """The raw values: int64 (or Python ints past 62 bits), float64 for IEEE signals."""
        bits = (word >> np.uint64(self.shift)) & np.uint64(self.mask)
        if self.is_float:
            ftype = {16: np.float16, 32: np.float32, 64: np.float64}[self.length]
            utype = {16: np.uint16, 32: np.uint32, 64: np.uint64}[self.length]
            with np.errstate(invalid="ignore"):     # a signalling NaN is made quiet, as in C
                return bits.astype(utype).view(ftype).astype(np.float64)
        if self.length >= 63 or self.object_math:
            vals = [int(b) for b in bits.tolist()]
            if self.signed:
                vals = [v - (1 << self.length) if v >> (self.length - 1) else v for v in vals]
            return np.array(vals, dtype=object)
        r = bits.astype(np.int64)
        if self.signed:
            r = np.where(r >> (self.length - 1) != 0, r - (1 << self.length), r)
        return r

    def scaled(self, word: np.ndarray) -> np.ndarray:
        """raw * scale + offset as cantools computes it (exact ints when both are ints)."""
        r = self.raw(word)
        if self.is_float:
            return r * self.scale + self.offset if (self.scale, self.offset) != (1, 0) \
                else r
        if self.int_math or self.object_math:
            v = r * self.scale + self.offset
            return np.array([float(x) for x in v], dtype=np.float64) if v.dtype == object \
                else v.astype(np.float64)
        return r.astype(np.float64) * self.scale + self.offset

    def packed(self, v: np.ndarray) -> np.ndarray:
        """The signal's bits in its 64-bit word, of values as cantools' scaled_to_raw
        takes them (round half to even, like Python's round)."""
        if self.is_float:
            x = v.astype(np.float64) if (self.scale, self.offset) == (1, 0) \
                else (v - self.offset) / self.scale
            ftype = {16: np.float16, 32: np.float32, 64: np.float64}[self.length]
            utype = {16: np.uint16, 32: np.uint32, 64: np.uint64}[self.length]
            bits = x.astype(ftype).view(utype).astype(np.uint64)
        else:
            raw = np.rint((v.astype(np.float64) - self.offset) / self.scale).astype(np.int64)
            bits = raw.view(np.uint64) & np.uint64(self.mask)
        return bits << np.uint64(self.shift)


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
