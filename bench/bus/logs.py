"""candump logs: tolerant reading, replay and decoding into a `Trace` through the DBC.

The format is ``candump -L`` (python-can's `CanutilsLogWriter`/`CanutilsLogReader`):
``(1700000000.123456) vcan0 190#E8030000400 R``. `read_log` reads it line by line and,
unlike `CanutilsLogReader` (which stops at the first bad line), reports each truncated
or corrupted line with its number and keeps the rest.

`trace_from_log` rebuilds the signal table: one row per SYNC (the control period), the
TPDOs (sensors at that SYNC), the ECU's set-point frame and its RPDO (the demand it
computed from them) that follow it. Missing SYNCs (counter jumps) leave NaN rows so
time stays aligned. The plant parameters the ECU read or wrote by SDO are recovered
from the SDO traffic in the log (expedited and segmented transfers), which gives the
SYNC period (0x1006) and the encoder resolution needed to turn counts into radians.
"""

from __future__ import annotations

import math
import re
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


@dataclass
class LogIssue:
    """A line of a log that could not be read."""
    line: int
    reason: str
    text: str

    def __str__(self) -> str:
        shown = self.text if len(self.text) <= 60 else self.text[:57] + "..."
        return f"line {self.line}: {self.reason}: {shown!r}"


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


def read_log(path: str | Path, issues: list[LogIssue] | None = None) -> Iterator[can.Message]:
    """The frames of a candump log; bad lines go to `issues` (line numbers from 1)."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such log: {path}")
    with path.open("r", errors="replace", newline="") as fh:
        for lineno, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            try:
                yield parse_line(line)
            except ValueError as exc:
                if issues is not None:
                    issues.append(LogIssue(lineno, str(exc), line.rstrip("\r\n")))


def report_issues(issues: list[LogIssue], limit: int = 20) -> list[str]:
    lines = [str(i) for i in issues[:limit]]
    if len(issues) > limit:
        lines.append(f"... and {len(issues) - limit} more bad lines")
    return lines


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


def trace_from_messages(messages: Iterable[can.Message], node_id: int | None = None,
                        period_s: float | None = None, counts_per_rev: int | None = None,
                        issues: list[LogIssue] | None = None, source: str = "log") -> Trace:
    """The signal table of a frame sequence (see module docstring)."""
    frames = Frames(node_id)
    od = load_od(frames.node_id)
    pobj = ParamObjects(od)
    sdo = SdoTracker(frames.sdo_rx, frames.sdo_tx)
    cob = frames.cob
    sync_cob, nmt_cob, emcy_cob = cob["SYNC"], cob["NMT"], cob["EMA_EMCY"]
    decoded_ids = {cob[n]: n for n in SIGNAL_COLUMNS}
    sync_max = int(od[0x1019].default)
    rows: list[dict[str, float]] = []
    cur: dict[str, float] | None = None
    first_ts: float | None = None
    last_counter: int | None = None
    run = 0
    n_frames = bad = short = gaps = 0
    emcy: list[dict[str, Any]] = []
    for msg in messages:
        n_frames += 1
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            continue
        cid = msg.arbitration_id
        if cid == sync_cob:
            if len(msg.data) not in (0, 1):
                bad += 1
                continue
            if first_ts is None:
                first_ts = msg.timestamp
            if len(msg.data) == 1:
                c = int(msg.data[0])
                if last_counter is not None:
                    step = (c - last_counter) % sync_max
                    for _ in range(max(0, step - 1)):      # lost SYNCs: keep time aligned
                        rows.append({"run": run})
                        gaps += 1
                last_counter = c
            cur = {"bus_time_s": msg.timestamp - first_ts, "run": run}
            rows.append(cur)
            continue
        if cid in (frames.sdo_rx, frames.sdo_tx):
            sdo.feed(msg)
            continue
        try:
            # process data of an older, shorter layout: keep the signals it carries
            decoded = frames.decode(msg, allow_truncated=cid in decoded_ids)
        except FrameError:
            bad += 1
            continue
        if decoded is None:
            continue
        if len(msg.data) < frames.by_cob[cid].length:   # older layout: the rest stays NaN
            short += 1
        name, sig = decoded
        if cid == nmt_cob:
            if (sig["NMT_Command"] == NMTCommand.START
                    and sig["NMT_NodeId"] in (0, frames.node_id)):
                run += 1
                last_counter = None
            continue
        if cid == emcy_cob:
            emcy.append({"row": len(rows) - 1, "code": int(sig["EMCY_ErrorCode"]),
                         "name": frames.label("EMA_EMCY", "EMCY_ErrorCode",
                                              sig["EMCY_ErrorCode"]),
                         "status_word": int(sig["EMCY_StatusWord"])})
            continue
        if cur is not None and cid in decoded_ids:
            for s, col in SIGNAL_COLUMNS[decoded_ids[cid]]:
                if s in sig:
                    cur[col] = float(sig[s])
    # parameters the SDO traffic revealed
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
    try:
        params = PlantParams().with_dict(values)
    except ParameterError:
        params = PlantParams()
    ts = period_s or params.sim.sync_period_s
    cpr = counts_per_rev or params.sensors.encoder_counts_per_rev
    n = len(rows)
    cols: dict[str, np.ndarray] = {"t_s": np.arange(n) * ts}
    for c in COLUMNS:
        cols[c] = np.array([r.get(c, np.nan) for r in rows], dtype=float)
    cols["motor_angle_rad"] = cols.pop("encoder_counts") * TWO_PI / cpr
    meta: dict[str, Any] = {
        "source": source, "node_id": frames.node_id, "period_s": ts, "counts_per_rev": cpr,
        "frames": n_frames, "bad_frames": bad, "short_frames": short, "sync_gaps": gaps,
        "runs": run,
        "emcy": emcy, "params_from_sdo": sorted(values),
        "issues": [{"line": i.line, "reason": i.reason} for i in (issues or [])[:100]],
        "issue_count": len(issues or []),
    }
    if len(values) >= len(pobj.by_name):
        meta["params"] = params.to_dict()
    return Trace(cols, meta)


def trace_from_log(path: str | Path, node_id: int | None = None, period_s: float | None = None,
                   counts_per_rev: int | None = None,
                   issues: list[LogIssue] | None = None) -> Trace:
    """The signal table of a candump log (for the HUMS, the gap diagnosis, `bench decode`).

    Bad lines are skipped and listed in ``trace.meta["issues"]`` (and in `issues` when
    given); the rest of the log is kept."""
    found: list[LogIssue] = [] if issues is None else issues
    tr = trace_from_messages(read_log(path, found), node_id, period_s, counts_per_rev,
                             found, source=str(path))
    if not len(tr) and not found:
        raise BenchError(f"{path}: no SYNC frame, so no control period to decode")
    return tr


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

