"""candump logs: tolerant reading, replay and decoding into a `Trace` through the DBC.

The format is ``candump -L`` (python-can's `CanutilsLogWriter`/`CanutilsLogReader`):
``(1700000000.123456) vcan0 190#E8030000400 R``. `read_log` streams it line by line and,
unlike `CanutilsLogReader` (which stops at the first bad line), reports each truncated
or corrupted line with its number and keeps the rest; bad lines are counted and only the
first ones kept (`LogIssues`), and a line is read MAX_LINE characters at most, so memory
stays bounded whatever the file holds.

`trace_from_log` rebuilds the signal table: one row per SYNC (the control period), the
TPDOs (sensors at that SYNC), the ECU's set-point frame and its RPDO (the demand it
computed from them) that follow it. Missing SYNCs (counter jumps) leave rows so time
stays aligned, filled with their frames when only the SYNC line is gone; frames missing
from a period, duplicates (never an extra row) and frames out of time order (the log is
then decoded in time-stamp order) are counted in the trace's metadata and `integrity`
words them. The plant parameters the ECU read or wrote by SDO are recovered from the SDO
traffic in the log (expedited and segmented transfers), which gives the SYNC period
(0x1006) and the encoder resolution needed to turn counts into radians.
"""

from __future__ import annotations

import functools
import math
import re
from array import array
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from bench import BenchError
from bench.trace import Trace
from ema_contract.frames import FrameError, Frames, load_od
from ema_contract.states import NMTCommand
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import ParameterError, PlantParams

LINE = re.compile(r"^\((?P<ts>\d+(?:\.\d*)?)\)\s+(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})"
                  r"#(?P<fd>#[0-9A-Fa-f])?(?P<data>[0-9A-Fa-f]*|R\d{0,2})(?:\s+(?P<dir>[RT]))?$")
FD_LENGTHS = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64}
TWO_PI = 2.0 * math.pi


MAX_LINE = 4096
"""Characters of a log line read at most: a candump -L line of a 64-byte CAN FD frame
has under 200; a longer line is reported and skipped in pieces (memory stays bounded)."""


@dataclass
class LogIssue:
    """A line of a log that could not be read (its text cut to 60 characters)."""
    line: int
    reason: str
    text: str

    def __post_init__(self) -> None:
        if len(self.text) > 60:
            self.text = self.text[:57] + "..."

    def __str__(self) -> str:
        return f"line {self.line}: {self.reason}: {self.text!r}"


class LogIssues:
    """Bad lines of a log: all counted, the first `keep` kept (memory bounded whatever
    the log). ``len()`` is the count; iteration gives the kept ones."""

    def __init__(self, keep: int = 20) -> None:
        self.keep = keep
        self.count = 0
        self.first: list[LogIssue] = []

    def append(self, issue: LogIssue) -> None:
        self.count += 1
        if len(self.first) < self.keep:
            self.first.append(issue)

    def __len__(self) -> int:
        return self.count

    def __iter__(self) -> Iterator[LogIssue]:
        return iter(self.first)


def parse_line(text: str) -> can.Message:
    """One candump -L line as a Message (ValueError with the reason if it is not one)."""
    s = text.strip()
    m = LINE.match(s)
    if m is None:
        if s.startswith("(") and ")" not in s:
            raise ValueError("truncated timestamp")
        if "#" not in s:
            raise ValueError("no frame (expected ID#DATA)")
        raise ValueError("not a candump -L frame")
    ident, data, fd = m["id"], m["data"], m["fd"]
    can_id = int(ident, 16)
    ext = len(ident) == 8
    if not ext and can_id > 0x7FF:
        raise ValueError(f"standard id 0x{can_id:X} above 0x7FF")
    if ext and can_id & 0x20000000:     # error frame as written by CanutilsLogWriter
        return can.Message(timestamp=float(m["ts"]), is_error_frame=True)
    if data.startswith("R"):
        if fd:
            raise ValueError("remote frame in CAN FD")
        dlc = int(data[1:]) if len(data) > 1 else 0
        if dlc > 8:
            raise ValueError(f"remote frame DLC {dlc} above 8")
        return can.Message(timestamp=float(m["ts"]), arbitration_id=can_id & 0x1FFFFFFF,
                           is_extended_id=ext, is_remote_frame=True, dlc=dlc,
                           channel=m["ch"], is_rx=m["dir"] != "T")
    if len(data) % 2:
        raise ValueError("odd number of hex digits (truncated data)")
    payload = bytes.fromhex(data)
    if fd:
        if len(payload) not in FD_LENGTHS:
            raise ValueError(f"CAN FD frame of {len(payload)} bytes")
        flags = int(fd[1], 16)
        return can.Message(timestamp=float(m["ts"]), arbitration_id=can_id, is_extended_id=ext,
                           is_fd=True, bitrate_switch=bool(flags & 1),
                           error_state_indicator=bool(flags & 2), data=payload,
                           channel=m["ch"], is_rx=m["dir"] != "T")
    if len(payload) > 8:
        raise ValueError(f"{len(payload)} data bytes in a classic CAN frame")
    return can.Message(timestamp=float(m["ts"]), arbitration_id=can_id, is_extended_id=ext,
                       data=payload, channel=m["ch"], is_rx=m["dir"] != "T")


def read_log(path: str | Path, issues: Any = None) -> Iterator[can.Message]:
    """The frames of a candump log, streamed; bad lines go to `issues` (anything with
    ``append``, e.g. a list or a `LogIssues`; line numbers from 1). BenchError when the
    file does not exist or cannot be read."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such log: {path}")
    try:
        fh = path.open("r", errors="replace", newline="")
    except OSError as exc:
        raise BenchError(f"cannot read {path}: {exc.strerror or exc}") from None
    with fh:
        for lineno, line in enumerate(_lines(fh), start=1):
            if line is None:
                if issues is not None:
                    issues.append(LogIssue(lineno, f"line longer than {MAX_LINE} characters",
                                           ""))
                continue
            if not line.strip():
                continue
            try:
                yield parse_line(line)
            except ValueError as exc:
                if issues is not None:
                    issues.append(LogIssue(lineno, str(exc), line.rstrip("\r\n")))


def _lines(fh: Any) -> Iterator[str | None]:
    """The lines of a text file, None for one longer than MAX_LINE (read in pieces)."""
    while True:
        line = fh.readline(MAX_LINE + 1)
        if not line:
            return
        if len(line) > MAX_LINE and not line.endswith("\n"):
            while line and not line.endswith("\n"):
                line = fh.readline(MAX_LINE)
            yield None
        else:
            yield line


def report_issues(issues: Any, limit: int = 20) -> list[str]:
    """The first `limit` bad lines as text, and how many more there are."""
    shown = [str(i) for _, i in zip(range(limit), issues, strict=False)]
    if len(issues) > len(shown):
        lines = shown + [f"... and {len(issues) - len(shown)} more bad lines"]
        return lines
    return shown


# -- SDO traffic --------------------------------------------------------------------------
@dataclass
class _Transfer:
    index: int
    sub: int
    upload: bool
    data: bytearray = field(default_factory=bytearray)
    size: int | None = None


class SdoTracker:
    """Values that crossed an SDO server (CiA 301 expedited and segmented transfers),
    confirmed by the server: object (index, sub) -> raw bytes, in log order."""

    def __init__(self, rx_cob: int, tx_cob: int) -> None:
        self.rx_cob, self.tx_cob = rx_cob, tx_cob
        self.values: dict[tuple[int, int], bytes] = {}
        self._req: _Transfer | None = None
        self._pending_write: _Transfer | None = None

    def feed(self, msg: can.Message) -> None:
        d = bytes(msg.data)
        if len(d) != 8:
            return
        cmd = d[0]
        if msg.arbitration_id == self.rx_cob:          # client -> server
            ccs = cmd >> 5
            if ccs == 1:                                 # initiate download
                t = _Transfer(d[1] | d[2] << 8, d[3], False)
                if cmd & 0x2:                            # expedited
                    n = 4 - ((cmd >> 2) & 0x3) if cmd & 0x1 else 4
                    t.data += d[4:4 + n]
                    t.size = n
                elif cmd & 0x1:
                    t.size = int.from_bytes(d[4:8], "little")
                self._pending_write = t
            elif ccs == 0 and self._pending_write is not None:   # download segment
                n = 7 - ((cmd >> 1) & 0x7)
                self._pending_write.data += d[1:1 + n]
                if cmd & 0x1:
                    self._pending_write.size = len(self._pending_write.data)
            elif ccs == 2:                               # initiate upload
                self._req = _Transfer(d[1] | d[2] << 8, d[3], True)
        elif msg.arbitration_id == self.tx_cob:        # server -> client
            scs = cmd >> 5
            if scs == 4:                                 # abort
                self._req = self._pending_write = None
            elif scs == 3 and self._pending_write is not None:   # download confirmed
                t = self._pending_write
                if t.size is not None and len(t.data) >= t.size:
                    self.values[(t.index, t.sub)] = bytes(t.data[:t.size])
                    self._pending_write = None
            elif scs == 1 and self._pending_write is not None:   # segment confirmed
                t = self._pending_write
                if t.size is not None and len(t.data) >= t.size:
                    self.values[(t.index, t.sub)] = bytes(t.data[:t.size])
                    self._pending_write = None
            elif scs == 2 and self._req is not None:     # initiate upload response
                t = self._req
                if cmd & 0x2:
                    n = 4 - ((cmd >> 2) & 0x3) if cmd & 0x1 else 4
                    self.values[(t.index, t.sub)] = d[4:4 + n]
                    self._req = None
                else:
                    t.size = int.from_bytes(d[4:8], "little") if cmd & 0x1 else None
            elif scs == 0 and self._req is not None:     # upload segment
                t = self._req
                n = 7 - ((cmd >> 1) & 0x7)
                t.data += d[1:1 + n]
                if cmd & 0x1:
                    self.values[(t.index, t.sub)] = bytes(t.data if t.size is None
                                                          else t.data[:t.size])
                    self._req = None


# -- decoding -----------------------------------------------------------------------------
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


@dataclass
class _Group:
    """The row frames of one SYNC period: frame name -> (payload, {column: value})."""
    frames: dict[str, tuple[bytes, dict[str, float]]] = field(default_factory=dict)

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
    """The signal table as it grows: one compact column per signal, plus which row
    frames each row received (bit i: ROW_FRAMES[i])."""

    def __init__(self) -> None:
        self.cols = {c: array("d") for c in COLUMNS}
        self.present = array("B")

    def __len__(self) -> int:
        return len(self.present)

    def add(self, bus_time_s: float, run: int, group: _Group | None) -> None:
        values: dict[str, float] = {"bus_time_s": bus_time_s, "run": float(run)}
        mask = 0
        if group is not None:
            for name, (_, vals) in group.frames.items():
                values.update(vals)
                mask |= 1 << ROW_FRAMES.index(name)
        for c, col in self.cols.items():
            col.append(values.get(c, math.nan))
        self.present.append(mask)

    def missing(self, seen: set[str]) -> dict[str, int]:
        """Per row frame seen in the log: the rows (SYNC periods) without it."""
        mask = np.frombuffer(self.present, dtype=np.uint8) if len(self) else np.zeros(0, int)
        return {name: int(np.sum((mask & (1 << i)) == 0))
                for i, name in enumerate(ROW_FRAMES) if name in seen}


class _Decoder:
    """Frames in log order -> rows, one per SYNC period, with the log's damage counted
    (see `trace_from_messages`)."""

    def __init__(self, frames: Frames, sync_max: int) -> None:
        self.f = frames
        cob = frames.cob
        self.sync_cob, self.nmt_cob, self.emcy_cob = cob["SYNC"], cob["NMT"], cob["EMA_EMCY"]
        self.row_ids = {cob[n]: n for n in ROW_FRAMES}
        self.sync_max = sync_max
        self.sdo = SdoTracker(frames.sdo_rx, frames.sdo_tx)
        self.rows = _Rows()
        self.open: _Period | None = None
        self.first_ts: float | None = None
        self.last_counter: int | None = None
        self.run = 0
        self.syncs_in_run = self.syncs_read = 0
        self.seen: set[str] = set()
        self.emcy: list[dict[str, Any]] = []
        self.count = dict(frames=0, bad_frames=0, short_frames=0, sync_gaps=0,
                          sync_recovered=0, duplicate_frames=0, replaced_frames=0,
                          out_of_order=0, emcy_count=0)
        self.check_order = True
        self.stop_on_disorder = False
        self._max_ts = self._max_sync_ts = -math.inf
        self._same_ts: set[tuple] = set()
        self._last_ts: float | None = None

    # -- frame by frame --------------------------------------------------------------
    def feed(self, msg: can.Message) -> None:
        c = self.count
        c["frames"] += 1
        ts = float(msg.timestamp)
        if self.check_order:
            self.order(msg)
            if self.stop_on_disorder and c["out_of_order"]:
                raise _OutOfOrder
        if self._exact_duplicate(msg, ts):
            c["duplicate_frames"] += 1
            return
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        cid = msg.arbitration_id
        if cid == self.sync_cob:
            self._sync(msg, ts)
        elif cid in (self.f.sdo_rx, self.f.sdo_tx):
            self.sdo.feed(msg)
        else:
            self._data(msg, cid)

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

    def _exact_duplicate(self, msg: can.Message, ts: float) -> bool:
        """The same frame with the same time stamp as one already read in this SYNC
        period: one frame logged twice (a classic CAN frame lasts >= 47 us at 1 Mbit/s,
        so two frames never share a microsecond stamp)."""
        key = (msg.arbitration_id, bytes(msg.data), msg.is_extended_id, msg.is_remote_frame,
               msg.is_error_frame, msg.is_fd, msg.dlc, msg.is_rx)
        if ts != self._last_ts or len(self._same_ts) > _MAX_SAME_TS:
            self._same_ts.clear()
            self._last_ts = ts
        elif key in self._same_ts:
            return True
        if msg.arbitration_id == self.sync_cob and not msg.is_extended_id:
            self._same_ts.clear()      # a new SYNC period; its copy still matches below
        self._same_ts.add(key)
        return False

    def _sync(self, msg: can.Message, ts: float) -> None:
        if len(msg.data) not in (0, 1):
            self.count["bad_frames"] += 1
            return
        lost = None
        if len(msg.data) == 1:
            counter = int(msg.data[0])
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

    def _data(self, msg: can.Message, cid: int) -> None:
        try:
            # process data of an older, shorter layout: keep the signals it carries
            decoded = self.f.decode(msg, allow_truncated=cid in self.row_ids)
        except FrameError:
            self.count["bad_frames"] += 1
            return
        if decoded is None:
            return
        if len(msg.data) < self.f.by_cob[cid].length:   # older layout: the rest stays NaN
            self.count["short_frames"] += 1
        name, sig = decoded
        if cid == self.nmt_cob:
            self._nmt(sig)
        elif cid == self.emcy_cob:
            self._emcy(sig)
        elif cid in self.row_ids and self.open is not None:
            self._row_frame(name, bytes(msg.data), sig)

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

    def _row_frame(self, name: str, data: bytes, sig: dict[str, Any]) -> None:
        assert self.open is not None
        groups = self.open.groups
        if any(g.holds(name, data) for g in groups):     # the same frame again
            self.count["duplicate_frames"] += 1
            return
        if name in groups[-1].frames:
            groups.append(_Group())
        self.seen.add(name)
        groups[-1].frames[name] = (data, {col: float(sig[s]) for s, col in
                                          SIGNAL_COLUMNS[name] if s in sig})

    def finish(self) -> _Rows:
        self._close(None)
        return self.rows


class _OutOfOrder(Exception):
    """Raised by a decoder told to stop at the first frame out of time order."""


FRAME_DTYPE = np.dtype([("ts", "f8"), ("id", "u4"), ("flags", "u1"), ("dlc", "u1"),
                        ("len", "u1"), ("data", "V8")])
_FLAGS = ("is_extended_id", "is_remote_frame", "is_error_frame", "is_fd", "bitrate_switch",
          "error_state_indicator", "is_rx")


def time_ordered(messages: Iterable[can.Message], chunk: int = 65536
                 ) -> Iterator[can.Message]:
    """The frames sorted by time stamp (stable: equal stamps keep their order), held as
    packed records of 23 bytes (CAN FD payloads over 8 bytes aside) rather than as
    can.Message objects: a 30 MB log sorts within ~20 MB."""
    parts: list[np.ndarray] = []
    buf = np.zeros(chunk, FRAME_DTYPE)
    long: dict[int, bytes] = {}
    n = k = 0
    for m in messages:
        data = bytes(m.data)
        if len(data) > 8:
            long[n] = data
        buf[k] = (float(m.timestamp), m.arbitration_id,
                  sum(1 << i for i, f in enumerate(_FLAGS) if getattr(m, f)), m.dlc,
                  min(len(data), 8), data[:8].ljust(8, b"\0"))
        n += 1
        k += 1
        if k == chunk:
            parts.append(buf)
            buf = np.zeros(chunk, FRAME_DTYPE)
            k = 0
    parts.append(buf[:k])
    rec = np.concatenate(parts)
    del parts, buf
    for i in np.argsort(rec["ts"], kind="stable"):
        r = rec[i]
        flags = int(r["flags"])
        data = long.get(int(i)) or bytes(r["data"])[:int(r["len"])]
        kw = {f: bool(flags >> b & 1) for b, f in enumerate(_FLAGS)}
        yield can.Message(timestamp=float(r["ts"]), arbitration_id=int(r["id"]),
                          dlc=int(r["dlc"]), data=None if kw["is_remote_frame"] else data,
                          **kw)


@functools.lru_cache(maxsize=4)
def _codec(node_id: int | None) -> tuple[Frames, Any, ParamObjects]:
    """The DBC frames, object dictionary and parameter objects of node `node_id` (parsed
    once: the EDS takes ~20 ms). BenchError for an id CANopen does not allow."""
    try:
        frames = Frames(node_id)
    except ValueError as exc:
        raise BenchError(str(exc)) from None
    od = load_od(frames.node_id)
    return frames, od, ParamObjects(od)


def trace_from_messages(messages: Iterable[can.Message], node_id: int | None = None,
                        period_s: float | None = None, counts_per_rev: int | None = None,
                        issues: Any = None, source: str = "log",
                        sort_by_time: bool = False, stop_on_disorder: bool = False) -> Trace:
    """The signal table of a frame sequence, one row per SYNC period (module docstring).

    Damage is counted in ``trace.meta``, never guessed away:
    - ``sync_gaps``: lost SYNCs (counter jumps); each leaves a row so time stays aligned.
      When only the SYNC line is missing, the frames that followed it come again with
      other content in the previous period: they fill the lost SYNC's row
      (``sync_recovered``) instead of overwriting the previous one. Where no counter
      tells (the log's last period, SYNCs without counter), frames led by a new ECU
      set-point are taken as such a period.
    - ``missing_frames``: per row frame (set-point, RPDO1, TPDO1-3) seen in the log, the
      SYNC periods without it (their columns are NaN there).
    - ``duplicate_frames``: a frame logged twice (same stamp), the same row frame twice in
      one SYNC period, or a repeated SYNC counter: dropped, never an extra row; a repeated
      NMT start without SYNC in between does not begin a new run.
    - ``replaced_frames``: a row frame that came twice with other content in one period
      without a lost SYNC to explain it (a late frame of a real-time log): the later one.
    - ``out_of_order``: frames stamped more than OUT_OF_ORDER_S before an earlier line,
      and SYNCs stamped before an earlier SYNC. With `sort_by_time` the frames are
      decoded in time-stamp order (a stable sort, `time_ordered`) instead of log order;
      `stop_on_disorder` raises _OutOfOrder at the first such frame instead (a shuffled
      log read in its order would only make rows of garbage).

    BenchError when the SYNC counters claim more lost SYNCs than MAX_LOST_SYNCS allows
    (or `node_id` is not a CANopen node id); nothing else is raised for any frames.
    """
    frames, od, pobj = _codec(node_id)
    dec = _Decoder(frames, int(od[0x1019].default))
    if sort_by_time:
        messages = time_ordered(_counting_order(messages, dec))
        dec.check_order = False
    dec.stop_on_disorder = stop_on_disorder
    for msg in messages:
        dec.feed(msg)
    rows = dec.finish()
    values = _sdo_values(dec.sdo, pobj, od)
    try:
        params = PlantParams().with_dict(values)
    except ParameterError:
        params = PlantParams()
    ts = period_s or params.sim.sync_period_s
    cpr = counts_per_rev or params.sensors.encoder_counts_per_rev
    n = len(rows)
    cols: dict[str, np.ndarray] = {"t_s": np.arange(n) * ts}
    for c in COLUMNS:
        cols[c] = np.frombuffer(rows.cols[c], dtype=float).copy() if n else np.zeros(0)
    cols["motor_angle_rad"] = cols.pop("encoder_counts") * TWO_PI / cpr
    kept = list(issues or [])[:100]
    meta: dict[str, Any] = {
        "source": source, "node_id": frames.node_id, "period_s": ts, "counts_per_rev": cpr,
        **dec.count, "missing_frames": rows.missing(dec.seen), "sorted_by_time": sort_by_time,
        "runs": dec.run, "emcy": dec.emcy, "params_from_sdo": sorted(values),
        "issues": [{"line": i.line, "reason": i.reason} for i in kept],
        "issue_count": len(issues or []),
    }
    if len(values) >= len(pobj.by_name):
        meta["params"] = params.to_dict()
    return Trace(cols, meta)


def _counting_order(messages: Iterable[can.Message], dec: _Decoder
                    ) -> Iterator[can.Message]:
    """`messages` unchanged, each counted by `dec.order` (in log order) on the way."""
    for m in messages:
        dec.order(m)
        yield m


def _sdo_values(sdo: SdoTracker, pobj: ParamObjects, od: Any) -> dict[str, Any]:
    """The plant parameters the SDO traffic revealed (name -> value)."""
    values: dict[str, Any] = {}
    for (idx, sub), raw in sdo.values.items():
        po = pobj.by_key.get((idx, sub))
        if po is None:
            continue
        try:
            values[po.info.name] = ParamObjects.from_od(po.info, od[idx][sub].decode_raw(raw))
        except Exception:  # noqa: BLE001 - a garbled transfer is skipped, not fatal
            continue
    if (0x1006, 0) in sdo.values:
        try:
            us = od[0x1006].decode_raw(sdo.values[(0x1006, 0)])
            values.setdefault("sim.sync_period_s", us * 1e-6)
        except Exception:  # noqa: BLE001
            pass
    return values


def trace_from_log(path: str | Path, node_id: int | None = None, period_s: float | None = None,
                   counts_per_rev: int | None = None,
                   issues: Any = None) -> Trace:
    """The signal table of a candump log (for the HUMS, the gap diagnosis, `bench decode`).

    Bad lines are skipped, counted and the first ones listed in ``trace.meta["issues"]``
    (and collected in `issues` when given: a list or a `LogIssues`); the rest of the log
    is kept. A log whose frames are out of time order (``meta["out_of_order"]``) is
    decoded again in time-stamp order (``meta["sorted_by_time"]``): every stamp of a log
    is the time its frame was on the bus, taken on one clock, so the stamps keep the bus
    order that an edited or merged file lost. BenchError when no SYNC period is found."""
    found = LogIssues(100) if issues is None else issues
    first = _Counted(found)
    try:
        tr = trace_from_messages(read_log(path, first), node_id, period_s, counts_per_rev,
                                 found, source=str(path), stop_on_disorder=True)
    except _OutOfOrder:        # read it all again, in time-stamp order
        tr = trace_from_messages(read_log(path, _Counted(found, skip=first.seen)), node_id,
                                 period_s, counts_per_rev, found, source=str(path),
                                 sort_by_time=True)
    if not len(tr):
        n = len(found)
        first = next(iter(found), None)
        raise BenchError(f"{path}: nothing to decode: {tr.meta['frames']} frames, no SYNC "
                         f"frame, so no control period"
                         + (f"; {n} bad lines ({first})" if n else ""))
    return tr


class _Counted:
    """Passes issues on to `target`, skipping the first `skip` (already passed on by an
    earlier read of the same file), and counts them."""

    def __init__(self, target: Any, skip: int = 0) -> None:
        self.target, self.skip, self.seen = target, skip, 0

    def append(self, issue: LogIssue) -> None:
        if self.seen >= self.skip:
            self.target.append(issue)
        self.seen += 1


def _n(count: int, word: str, plural: str | None = None) -> str:
    return f"{count} {word if count == 1 else (plural or word + 's')}"


def integrity(meta: dict[str, Any]) -> list[str]:
    """What a decoded log lost, repeated or had out of order (and the NaN blocks of a
    table from `bench import`), as short phrases, empty for an intact source: for
    `bench decode`, `bench import`, the HUMS report and the gap diagnosis."""
    out = []
    gaps = int(meta.get("sync_gaps") or 0)
    if gaps:
        rec = int(meta.get("sync_recovered") or 0)
        out.append(_n(gaps, "lost SYNC") + (f" ({rec} recovered from {'its' if rec == 1 else 'their'}"
                                             " frames)" if rec else ""))
    missing = {k: v for k, v in (meta.get("missing_frames") or {}).items() if v}
    if missing:
        out.append("missing: " + ", ".join(f"{k} in {_n(v, 'period')}"
                                           for k, v in missing.items()))
    dup = int(meta.get("duplicate_frames") or 0)
    if dup:
        out.append(f"{_n(dup, 'duplicate frame')} dropped")
    rep = int(meta.get("replaced_frames") or 0)
    if rep:
        out.append(f"{_n(rep, 'frame')} replaced by a later one of the same SYNC period")
    ooo = int(meta.get("out_of_order") or 0)
    if ooo:
        out.append(f"{_n(ooo, 'frame')} out of time order: decoded in "
                   + ("time-stamp order" if meta.get("sorted_by_time") else "log order"))
    for b in meta.get("nan_blocks") or []:        # an imported table (bench import)
        out.append(f"NaN block in {b['column']} ({b['signal']}): table rows "
                   f"{b['first_row']}-{b['last_row']}, t = {b['t0_s']:.3f}-{b['t1_s']:.3f} s, "
                   f"{_n(b['samples'], 'SYNC sample')} left empty")
    return out


TABLE_SUFFIXES = (".npz", ".csv", ".parquet")


def load_trace(path: str | Path) -> Trace:
    """A candump log (decoded through the DBC) or a saved trace table (.npz, .csv,
    .parquet) as a Trace; BenchError naming the file when it cannot be read."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such file: {path}")
    suffix = path.suffix.lower()
    if suffix == ".log":
        tr = trace_from_log(path)
    elif suffix in TABLE_SUFFIXES:
        tr = Trace.load(path)
    else:
        raise BenchError(f"{path}: unknown log format {suffix!r} (a candump .log, or a "
                         f"trace {', '.join(TABLE_SUFFIXES)})")
    tr.meta.setdefault("source", str(path))
    return tr

