"""Frames -> the signal table, one row per SYNC period: the one row assembler of the bus
logs (`bench.bus.logs.trace_from_messages`) and of the live HUMS (`bench.hums.live`).

A row holds the SYNC's bus time, the TPDOs (sensors at that SYNC), the ECU's set-point
frame and its RPDO (the demand it computed from them) that follow it. `RowAssembler`
takes frames one at a time, in the order given, and writes a period's rows into its row
sink when the period closes (the next SYNC, an NMT start, `finish`). Missing SYNCs
(counter jumps) leave rows so time stays aligned, filled with their frames when only the
SYNC line is gone; frames missing from a period, duplicates (never an extra row), late
frames and frames out of time order are counted in ``count`` (see
`bench.bus.logs.trace_from_messages` for each word). Sorting a shuffled log by time
stamp needs the whole log: that step is the log decoder's (`bench.bus.logs.time_ordered`),
not this module's; a live listener gets the frames in bus order.

Speed (a fleet's logs are mostly clean): a classic data frame can be fed as
plain values (`RowAssembler.feed_frame`, what `bench.bus.logread.read_log` gives with
``raw=True``) instead of a can.Message; the default row sink (`_Rows`) keeps each row
frame's payload and decodes them all at once when the table is asked for
(`trace_columns`), through the DBC's vectorised codec (`ema_contract.frames.PayloadCodec`,
bit-identical to cantools'); frames are checked by length only until then. A row sink
of its own (the live HUMS) still gets each frame's values as it comes, decoded by
cantools.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from bench import BenchError
from bench.bus.sdo import SdoTracker
from ema_contract.frames import FrameError, Frames
from ema_contract.states import NMTCommand

COLUMNS = ("setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
           "current_a", "motor_speed_rad_s", "encoder_counts", "position_m",
           "winding_temperature_k", "load_force_n", "status_word", "bus_time_s", "run")
SIGNAL_COLUMNS = {
    "ECU_Setpoint": (("SetpointPosition", "setpoint_position_m"),
                     ("SetpointSpeed", "setpoint_speed_rad_s"), ("Mode", "mode")),
    "EMA_RPDO1": (("CurrentDemand", "current_demand_a"),),
    "EMA_TPDO1": (("MotorCurrent", "current_a"), ("StatusWord", "status_word")),
    "EMA_TPDO2": (("EncoderAngle", "encoder_counts"), ("EncoderSpeed", "motor_speed_rad_s")),
    "EMA_TPDO3": (("LvdtPosition", "position_m"), ("WindingTemperature",
                                                   "winding_temperature_k"),
                  ("LoadForce", "load_force_n")),
}


ROW_FRAMES = ("ECU_Setpoint", "EMA_TPDO1", "EMA_TPDO2", "EMA_TPDO3", "EMA_RPDO1")
"""Frames that fill a SYNC period's row (one of each per period)."""
OUT_OF_ORDER_S = 1.0
"""A frame stamped more than this before an earlier line of the log is out of time order
(and so is a SYNC stamped before an earlier SYNC: one producer, one clock). A live log
interleaves two clocks' stamps: the ECU stamps its own frames as it logs them, received
frames carry the bus's stamp and reach the log when the ECU's receive thread gets to
them, which puts a TPDO ~1 ms before the set-point logged ahead of it and the plant's
heartbeats up to 0.17 s (measured) behind the run's first frames. A frame 1 s late would
have ended the run (the ECU gives up after 1 s without TPDO)."""
MAX_LOST_SYNCS = (2.0, 1000)
"""Lost SYNCs believed at most: twice the SYNCs read plus 1000. Each counter jump adds
up to 239 empty rows, so a log of garbage counters would otherwise grow the table 239
times its SYNC lines; a log that lost more than that is refused (BenchError)."""
MAX_EMCY_KEPT = 1000
_MAX_SAME_TS = 4096
TWO_PI = 2.0 * math.pi


@dataclass
class _Group:
    """The row frames of one SYNC period: frame name -> (payload, {column: value}, or
    None when the row sink decodes the payloads itself)."""
    frames: dict[str, tuple[bytes, dict[str, float] | None]] = field(default_factory=dict)

    def holds(self, name: str, data: bytes) -> bool:
        got = self.frames.get(name)
        return got is not None and got[0] == data


@dataclass
class _Period:
    """An open SYNC period: its bus time and the groups of frames that followed its SYNC
    (a second group starts when a frame kind comes again with other content: the frames
    of a following period whose SYNC line is missing, or a late frame)."""
    bus_time_s: float
    run: int
    groups: list[_Group] = field(default_factory=lambda: [_Group()])


class _Rows:
    """The signal table as it grows: per row its bus time, its run and the payload of
    each row frame it received (zeros and length 0 for none; bit i of `present`:
    ROW_FRAMES[i] received), decoded column by column by `columns`."""

    takes_payloads = True
    """The assembler gives this sink payloads, not values (it decodes them itself)."""

    def __init__(self, frames: Frames) -> None:
        self.frames = frames
        self.bus_time = array("d")
        self.run = array("d")
        self.present = array("B")
        self.stride = [frames.by_name[n].length for n in ROW_FRAMES]
        self.payload = [bytearray() for _ in ROW_FRAMES]
        self.length = [array("B") for _ in ROW_FRAMES]
        self._slots = list(zip(ROW_FRAMES, self.stride, self.length, self.payload, strict=True))

    def __len__(self) -> int:
        return len(self.present)

    def add(self, bus_time_s: float, run: int, group: _Group | None) -> None:
        self.bus_time.append(bus_time_s)
        self.run.append(float(run))
        got = group.frames if group is not None else {}
        mask = 0
        for i, (name, stride, length, payload) in enumerate(self._slots):
            frame = got.get(name)
            if frame is None:
                length.append(0)
                payload += bytes(stride)
            else:
                data = frame[0]
                length.append(len(data))
                payload += data if len(data) == stride else data + bytes(stride - len(data))
                mask |= 1 << i
        self.present.append(mask)

    def columns(self, n: int) -> dict[str, np.ndarray]:
        """The COLUMNS of the first `n` rows (float64; NaN where a row has no frame, or a
        shorter frame of an older layout lacks the signal)."""
        if n == 0:
            return {c: np.zeros(0) for c in COLUMNS}
        out = {"bus_time_s": np.frombuffer(self.bus_time, dtype=float)[:n].copy(),
               "run": np.frombuffer(self.run, dtype=float)[:n].copy()}
        for i, name in enumerate(ROW_FRAMES):
            lengths = np.frombuffer(self.length[i], dtype=np.uint8)[:n]
            payloads = np.frombuffer(bytes(self.payload[i]), dtype=np.uint8)
            payloads = payloads.reshape(-1, self.stride[i])[:n]
            sig = _decode_rows(self.frames, name, payloads, lengths)
            for s, col in SIGNAL_COLUMNS[name]:
                out[col] = sig[s] if s in sig else np.full(n, math.nan)
        return {c: out[c] for c in COLUMNS}

    def missing(self, seen: set[str]) -> dict[str, int]:
        """Per row frame seen in the log: the rows (SYNC periods) without it."""
        mask = np.frombuffer(self.present, dtype=np.uint8) if len(self) else np.zeros(0, int)
        return {name: int(np.sum((mask & (1 << i)) == 0))
                for i, name in enumerate(ROW_FRAMES) if name in seen}


def _decode_rows(frames: Frames, name: str, payloads: np.ndarray, lengths: np.ndarray
                 ) -> dict[str, np.ndarray]:
    """Signal -> values of frame `name` in each row (NaN: no frame, or a signal a short
    frame does not hold): the DBC's vectorised codec, or cantools frame by frame for a
    message it does not handle (multiplexed, over 8 bytes)."""
    codec = frames.codec(name)
    if codec is not None:
        return codec.decode(payloads, lengths)
    m = frames.by_name[name]
    out = {s.name: np.full(len(lengths), math.nan) for s in m.signals}
    for k in np.flatnonzero(lengths):
        n = int(lengths[k])
        sig = m.decode_simple(payloads[k, :n].tobytes(), decode_choices=False, scaling=True,
                              allow_truncated=n < m.length)
        for s, v in sig.items():
            out[s][k] = float(v)  # type: ignore[arg-type]  # numbers: no choices
    return out


def trace_columns(rows: Any, period_s: float, counts_per_rev: float,
                  periods: int | None = None) -> dict[str, np.ndarray]:
    """The trace columns of the rows a `RowAssembler` wrote into its default sink: `t_s`
    on the SYNC grid of `period_s`, every COLUMNS signal, the encoder counts as
    `motor_angle_rad` (`counts_per_rev`); the first `periods` rows when given (the ECU's
    periods done), all of them otherwise."""
    n = len(rows) if periods is None else min(periods, len(rows))
    cols: dict[str, np.ndarray] = {"t_s": np.arange(n) * period_s}
    cols.update(rows.columns(n))
    cols["motor_angle_rad"] = cols.pop("encoder_counts") * TWO_PI / counts_per_rev
    return cols


def out_of_range(frames: Frames, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per row frame: the rows (a mask) whose frame decodes to a value outside its
    signal's range in the DBC, where that range is narrower than what the signal's bits
    can hold (the set-point's mode 0-2, the demand's +-1000 A): a frame of another
    layout. `blank_out_of_range` empties them."""
    out: dict[str, np.ndarray] = {}
    for name in ROW_FRAMES:
        msg = frames.by_name[name]
        bad = np.zeros(len(cols["t_s"]), bool)
        for sig, col in SIGNAL_COLUMNS[name]:
            s = msg.get_signal_by_name(sig)
            if s.minimum is None or s.maximum is None or col not in cols:
                continue
            lo, hi = _bits_range(s)
            if s.minimum <= lo and s.maximum >= hi:
                continue
            v = cols[col]
            with np.errstate(invalid="ignore"):
                bad |= (v < s.minimum) | (v > s.maximum)
        if bad.any():
            out[name] = bad
    return out


def blank_out_of_range(cols: dict[str, np.ndarray], bad: dict[str, np.ndarray]) -> None:
    """NaN every column of a row frame in the rows `bad` marks (`out_of_range`): its
    numbers are not this layout's."""
    for name, mask in bad.items():
        for _, col in SIGNAL_COLUMNS[name]:
            col = "motor_angle_rad" if col == "encoder_counts" else col
            if col in cols:
                cols[col][mask] = math.nan


def _bits_range(s: Any) -> tuple[float, float]:
    """The lowest and highest value a DBC signal's bits can hold, scaled."""
    if s.is_float:
        return -math.inf, math.inf
    lo, hi = (-(1 << (s.length - 1)), (1 << (s.length - 1)) - 1) if s.is_signed \
        else (0, (1 << s.length) - 1)
    a, b = lo * s.scale + s.offset, hi * s.scale + s.offset
    return min(a, b), max(a, b)


class RowAssembler:
    """Frames in log order -> rows, one per SYNC period, with the log's damage counted
    (see `trace_from_messages`)."""

    def __init__(self, frames: Frames, sync_max: int, rows: Any = None) -> None:
        """`rows`: the sink of the rows (``add(bus_time_s, run, group)`` and ``len()``),
        a growing table (`_Rows`) when not given."""
        self.f = frames
        cob = frames.cob
        self.sync_cob, self.nmt_cob, self.emcy_cob = cob["SYNC"], cob["NMT"], cob["EMA_EMCY"]
        self.row_ids = {cob[n]: n for n in ROW_FRAMES}
        self.sync_max = sync_max
        self.sdo = SdoTracker(frames.sdo_rx, frames.sdo_tx)
        self._sdo_ids = (frames.sdo_rx, frames.sdo_tx)
        self.rows = _Rows(frames) if rows is None else rows
        self._values = not getattr(self.rows, "takes_payloads", False)
        self._kinds = _frame_kinds(frames, self.row_ids, (self.nmt_cob, self.emcy_cob))
        self.open: _Period | None = None
        self.first_ts: float | None = None
        self.last_counter: int | None = None
        self.run = 0
        self.syncs_in_run = self.syncs_read = 0
        self.seen: set[str] = set()
        self.emcy: list[dict[str, Any]] = []
        self.count = dict(frames=0, bad_frames=0, short_frames=0, sync_gaps=0,
                          sync_recovered=0, duplicate_frames=0, replaced_frames=0,
                          out_of_order=0, emcy_count=0, row_id_frames=0)
        self.misfit: dict[str, int] = {}
        """Per row frame: frames on its id whose length fits no layout of the DBC's."""
        self.check_order = True
        self.stop_on_disorder = False
        self._max_ts = self._max_sync_ts = -math.inf
        self._same_ts: set[tuple] = set()
        self._last_ts: float | None = None

    # -- frame by frame --------------------------------------------------------------
    def feed(self, msg: can.Message) -> None:
        data = bytes(msg.data)
        if not (msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame
                or msg.is_fd) and msg.dlc == len(data):
            self.feed_frame(float(msg.timestamp), msg.arbitration_id, data, msg.is_rx)
            return
        c = self.count                       # any other frame: counted, then CAN FD decoded
        c["frames"] += 1
        ts = float(msg.timestamp)
        if self.check_order:
            self.order(msg)
            if self.stop_on_disorder and c["out_of_order"]:
                raise _OutOfOrder
        key = (msg.arbitration_id, data, msg.is_extended_id, msg.is_remote_frame,
               msg.is_error_frame, msg.is_fd, msg.dlc, msg.is_rx)
        sync = msg.arbitration_id == self.sync_cob and not msg.is_extended_id
        if self._exact_duplicate(key, ts, sync):
            c["duplicate_frames"] += 1
            return
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        self._route(msg.arbitration_id, data, ts)

    def feed_frame(self, ts: float, cid: int, data: bytes, is_rx: bool = True) -> None:
        """`feed` of a classic data frame with an 11-bit id given as plain values (its
        time stamp, id, payload and direction): the same, without a can.Message."""
        c = self.count
        c["frames"] += 1
        sync = cid == self.sync_cob
        if self.check_order:
            late = ts < self._max_ts - OUT_OF_ORDER_S
            if sync:
                late = late or ts < self._max_sync_ts
                if ts > self._max_sync_ts:
                    self._max_sync_ts = ts
            if ts > self._max_ts:
                self._max_ts = ts
            if late:
                c["out_of_order"] += 1
                if self.stop_on_disorder:
                    raise _OutOfOrder
        if self._exact_duplicate((cid, data, is_rx), ts, sync):
            c["duplicate_frames"] += 1
            return
        if sync:
            self._sync(data, ts)
        elif cid in self._sdo_ids:
            self.sdo.feed(can.Message(arbitration_id=cid, data=data, is_extended_id=False))
        else:
            self._data(cid, data)

    def _route(self, cid: int, data: bytes, ts: float) -> None:
        if cid == self.sync_cob:
            self._sync(data, ts)
        elif cid in self._sdo_ids:
            self.sdo.feed(can.Message(arbitration_id=cid, data=data, is_extended_id=False))
        else:
            self._data(cid, data)

    def order(self, msg: can.Message) -> None:
        """Count `msg` as out of time order: stamped more than OUT_OF_ORDER_S before an
        earlier line, or a SYNC stamped before an earlier SYNC (one producer, one clock)."""
        ts = float(msg.timestamp)
        late = ts < self._max_ts - OUT_OF_ORDER_S
        if msg.arbitration_id == self.sync_cob and not msg.is_extended_id:
            late = late or ts < self._max_sync_ts
            self._max_sync_ts = max(self._max_sync_ts, ts)
        self.count["out_of_order"] += late
        self._max_ts = max(self._max_ts, ts)

    def _exact_duplicate(self, key: tuple, ts: float, sync: bool) -> bool:
        """The same frame (`key`: its id, payload and flags) with the same time stamp as
        one already read in this SYNC period: one frame logged twice (a classic CAN frame
        lasts >= 47 us at 1 Mbit/s, so two frames never share a microsecond stamp)."""
        same = self._same_ts
        if ts != self._last_ts or len(same) > _MAX_SAME_TS:
            same.clear()
            self._last_ts = ts
        elif key in same:
            return True
        if sync:
            same.clear()      # a new SYNC period; its copy still matches below
        same.add(key)
        return False

    def _sync(self, data: bytes, ts: float) -> None:
        if len(data) > 1:
            self.count["bad_frames"] += 1
            return
        lost = None
        if data:
            counter = data[0]
            if self.last_counter is not None:
                step = (counter - self.last_counter) % self.sync_max
                if step == 0:                       # the same SYNC again
                    self.count["duplicate_frames"] += 1
                    return
                lost = step - 1
            self.last_counter = counter
        if self.first_ts is None:
            self.first_ts = ts
        self.syncs_read += 1
        self._close(lost)
        self.syncs_in_run += 1
        self.open = _Period(ts - self.first_ts, self.run)

    def _close(self, lost: int | None) -> None:
        """Write the open period's rows: its own, then one per lost SYNC, filled with the
        frames that followed the missing SYNC line when the log has them. `lost` None: no
        SYNC counter tells (end of the log, a run's end, SYNCs without counter); then a
        group led by the ECU's set-point (sent right after each SYNC, never late) is the
        period of a lost SYNC line, and other groups are late frames."""
        p = self.open
        self.open = None
        if p is None:
            self.count["sync_gaps"] += lost or 0
            self._check_lost()
            for _ in range(lost or 0):
                self.rows.add(math.nan, self.run, None)
            return
        main, extra = p.groups[0], p.groups[1:]
        if lost is None:
            own = [g for g in extra if next(iter(g.frames)) == "ECU_Setpoint"]
            lost = len(own)
        else:
            own = extra[:lost]
        self.count["sync_gaps"] += lost
        self._check_lost()
        last = main
        for g in extra:
            if any(g is o for o in own):
                last = g
                continue
            for name, v in g.frames.items():     # no lost SYNC explains them: the later wins
                if name in last.frames:
                    self.count["replaced_frames"] += 1
                last.frames[name] = v
        self.rows.add(p.bus_time_s, p.run, main)
        for g in own:
            self.rows.add(math.nan, p.run, g)
        self.count["sync_recovered"] += len(own)
        for _ in range(lost - len(own)):
            self.rows.add(math.nan, p.run, None)

    def _check_lost(self) -> None:
        factor, slack = MAX_LOST_SYNCS
        if self.count["sync_gaps"] > factor * self.syncs_read + slack:
            raise BenchError(f"the SYNC counters make no sense: {self.count['sync_gaps']} "
                             f"SYNCs lost for {self.syncs_read} read (a corrupted log?)")

    def _data(self, cid: int, data: bytes) -> None:
        kind = self._kinds.get(cid)
        if kind is None:                  # an id the DBC does not describe
            return
        name, length, fits, row = kind
        n = len(data)
        if row:
            self.count["row_id_frames"] += 1
        if fits is None:                  # NMT, EMCY, a message without a codec: cantools
            self._decoded(cid, data)
            return
        if n != length:
            # process data of an older, shorter layout: keep the signals it carries
            if not row or n == 0 or n > length or not fits[n]:
                self.count["bad_frames"] += 1
                if row:
                    self.misfit[name] = self.misfit.get(name, 0) + 1
                return
            self.count["short_frames"] += 1
        if row and self.open is not None:
            self._row_frame(name, data, None)

    def _decoded(self, cid: int, data: bytes) -> None:
        """A frame decoded as it comes (cantools, `Frames.decode_payload`)."""
        try:
            decoded = self.f.decode_payload(cid, data, allow_truncated=cid in self.row_ids)
        except FrameError:
            self.count["bad_frames"] += 1
            if cid in self.row_ids:
                name = self.row_ids[cid]
                self.misfit[name] = self.misfit.get(name, 0) + 1
            return
        if decoded is None:
            return
        if len(data) < self.f.by_cob[cid].length:   # older layout: the rest stays NaN
            self.count["short_frames"] += 1
        name, sig = decoded
        if cid == self.nmt_cob:
            self._nmt(sig)
        elif cid == self.emcy_cob:
            self._emcy(sig)
        elif cid in self.row_ids and self.open is not None:
            self._row_frame(name, data, sig)

    def _nmt(self, sig: dict[str, Any]) -> None:
        if (sig["NMT_Command"] == NMTCommand.START
                and sig["NMT_NodeId"] in (0, self.f.node_id)):
            self._close(None)
            if self.run == 0 or self.syncs_in_run:     # a repeated start is the same run
                self.run += 1
            self.syncs_in_run = 0
            self.last_counter = None

    def _emcy(self, sig: dict[str, Any]) -> None:
        self.count["emcy_count"] += 1
        if len(self.emcy) < MAX_EMCY_KEPT:
            row = len(self.rows) - (0 if self.open is not None else 1)
            self.emcy.append({"row": row, "code": int(sig["EMCY_ErrorCode"]),
                              "name": self.f.label("EMA_EMCY", "EMCY_ErrorCode",
                                                   sig["EMCY_ErrorCode"]),
                              "status_word": int(sig["EMCY_StatusWord"])})

    def _row_frame(self, name: str, data: bytes, sig: dict[str, Any] | None) -> None:
        """A row frame of the open period; `sig` its signals when already decoded."""
        assert self.open is not None
        groups = self.open.groups
        for g in groups:
            got = g.frames.get(name)
            if got is not None and got[0] == data:     # the same frame again
                self.count["duplicate_frames"] += 1
                return
        if name in groups[-1].frames:
            groups.append(_Group())
        self.seen.add(name)
        vals = None
        if self._values:                  # a sink of values: decoded now
            if sig is None:
                decoded = self.f.decode_payload(self.f.cob[name], data, True)
                sig = decoded[1] if decoded is not None else {}
            vals = {col: float(sig[s]) for s, col in SIGNAL_COLUMNS[name] if s in sig}
        groups[-1].frames[name] = (data, vals)

    def close_period(self) -> None:
        """Write the open period's rows now (a live listener at an NMT stop: no SYNC
        follows, the period's frames have all come)."""
        self._close(None)

    def finish(self) -> Any:
        self._close(None)
        return self.rows


def _frame_kinds(frames: Frames, row_ids: dict[int, str], decoded: tuple[int, ...]
                 ) -> dict[int, tuple[str, int, list[bool] | None, bool]]:
    """Frame id -> (message name, DBC length, whether a payload of n bytes holds a whole
    signal (n = 0..length), is it a row frame) for the DBC's messages: a frame is checked
    by its length only (its signals are decoded later, or never); None in place of the
    list for the ids decoded as they come (`decoded`: NMT, EMCY; messages without a
    vectorised codec)."""
    out: dict[int, tuple[str, int, list[bool] | None, bool]] = {}
    for cid, m in frames.by_cob.items():
        codec = frames.codec(m.name)
        fits = None if codec is None or cid in decoded else \
            [bool(codec.fits(n)) for n in range(m.length + 1)]
        out[cid] = (m.name, m.length, fits, cid in row_ids)
    return out


class _OutOfOrder(Exception):
    """Raised by a decoder told to stop at the first frame out of time order."""
