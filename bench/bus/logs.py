"""Bus logs decoded into a `Trace` through the DBC: candump logs read tolerantly, and the
other formats python-can reads (`bench.bus.logread.read_frames`).

A candump ``-L`` log is read line by line and a bad line is reported with its number and
skipped (`bench.bus.logread.read_log`: how, and the bounds on memory).

`trace_from_log` rebuilds the signal table: one row per SYNC (the control period), the
TPDOs (sensors at that SYNC), the ECU's set-point frame and its RPDO (the demand it
computed from them) that follow it. Missing SYNCs (counter jumps) leave rows so time
stays aligned, filled with their frames when only the SYNC line is gone; frames missing
from a period, duplicates (never an extra row) and frames out of time order (the log is
then decoded in time-stamp order) are counted in the trace's metadata and `integrity`
words them. The plant parameters the ECU read or wrote by SDO are recovered from the SDO
traffic in the log (expedited and segmented transfers), which gives the SYNC period
(0x1006) and the encoder resolution needed to turn counts into radians.

The jobs live in their own modules: `bench.bus.logread` (the line reader),
`bench.bus.sdo` (the SDO tracker), `bench.bus.rows` (the row assembler, shared with the
live HUMS), `bench.signals.integrity` (the damage in words). This module puts them together
(and re-exports their names); sorting a shuffled log by time stamp (`time_ordered`)
needs the whole log and is done here only.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np

from bench import BenchError
from bench.bus.logread import (
    FD_LENGTHS,
    LINE,
    MAX_LINE,
    LogIssue,
    LogIssues,
    is_stdin,
    parse_line,
    read_frames,
    read_log,
    report_issues,
)
from bench.bus.logwrite import COMPRESSIONS, LOG_FORMATS, log_suffixes
from bench.bus.rows import (
    COLUMNS,
    MAX_EMCY_KEPT,
    MAX_LOST_SYNCS,
    OUT_OF_ORDER_S,
    ROW_FRAMES,
    SIGNAL_COLUMNS,
    RowAssembler,
    _OutOfOrder,
    blank_out_of_range,
    out_of_range,
    trace_columns,
)
from bench.bus.sdo import SdoTracker, sdo_values, serial_of
from bench.signals.integrity import integrity
from bench.signals.tables import TRACE_FORMATS
from bench.signals.trace import Trace
from ema_contract.frames import Frames, load_od
from ema_contract.states import Pace
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import ParameterError, PlantParams

__all__ = ["COLUMNS", "FD_LENGTHS", "LINE", "MAX_EMCY_KEPT", "MAX_LINE", "MAX_LOST_SYNCS",
           "OUT_OF_ORDER_S", "ROW_FRAMES", "SIGNAL_COLUMNS", "LogIssue", "LogIssues",
           "LOG_READERS", "SdoTracker", "integrity", "load_trace", "parse_line", "read_frames", "read_log",
           "report_issues",
           "time_ordered", "trace_from_log", "trace_from_messages"]

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


def trace_from_messages(messages: Iterable[Any], node_id: int | None = None,
                        period_s: float | None = None, counts_per_rev: int | None = None,
                        issues: Any = None, source: str = "log",
                        sort_by_time: bool = False, stop_on_disorder: bool = False) -> Trace:
    """The signal table of a frame sequence, one row per SYNC period (module docstring):
    can.Message objects, or the plain frames `read_log` gives as tuples with ``raw=True``
    (not with `sort_by_time`).

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
    dec = RowAssembler(frames, int(od[0x1019].default))
    if sort_by_time:
        messages = time_ordered(_counting_order(messages, dec))
        dec.check_order = False
    dec.stop_on_disorder = stop_on_disorder
    feed, feed_frame = dec.feed, dec.feed_frame
    for msg in messages:
        if type(msg) is tuple:      # a plain frame as values (`read_log` with raw=True)
            feed_frame(*msg)
        else:
            feed(msg)
    rows = dec.finish()
    values = sdo_values(dec.sdo, pobj, od)
    try:
        params = PlantParams().with_dict(values)
    except ParameterError:
        params = PlantParams()
    pace = dec.sdo.values.get((0x2200, 1))
    clock = log_clock(rows, period_s, values.get("sim.sync_period_s"),
                      pace is not None and int.from_bytes(pace, "little") == int(Pace.SYNC))
    ts = clock["period_s"] or params.sim.sync_period_s
    cpr = counts_per_rev or params.sensors.encoder_counts_per_rev
    cols = trace_columns(rows, ts, cpr)
    misfit = dict(dec.misfit)
    wrong = out_of_range(frames, cols)
    blank_out_of_range(cols, wrong)
    for name, mask in wrong.items():
        misfit[name] = misfit.get(name, 0) + int(mask.sum())
    kept = list(issues or [])[:100]
    meta: dict[str, Any] = {
        "source": source, "node_id": frames.node_id, "period_s": ts, "counts_per_rev": cpr,
        "clock": clock,
        **dec.count, "missing_frames": rows.missing(dec.seen), "sorted_by_time": sort_by_time,
        "runs": dec.run, "emcy": dec.emcy, "params_from_sdo": sorted(values),
        "misfit_frames": misfit,
        "row_frames_seen": sorted(dec.seen),
        "issues": [{"line": i.line, "reason": i.reason} for i in kept],
        "issue_count": len(issues or []),
    }
    if len(values) >= len(pobj.by_name):
        meta["params"] = params.to_dict()
    meta["actuator_serial"] = serial_of(dec.sdo, od)
    return Trace(cols, meta)


CLOCK_TOLERANCE = 0.1
"""The SYNC time stamps and the period the log's SDO traffic (0x1006) or --period gives
may differ by this share before the decoder warns."""


def log_clock(rows: Any, given: float | None, sdo: float | None, lockstep: bool
              ) -> dict[str, Any]:
    """The SYNC period of a log and where it comes from: `given` (--period), else the
    SDO 0x1006 read or written in the log, else the median interval of the SYNC time
    stamps (each counter step one period), else None (the default parameters'). A
    ``warning`` says when the stamps and the chosen period disagree by more than
    CLOCK_TOLERANCE, unless the log shows a lockstep run (pace object 0x2200 written
    SYNC: its stamps are the wall clock of a run faster than real time). ``sdo_period_s``
    keeps the SDO's period when --period overrides it."""
    stamps = _stamp_period(rows)
    chosen, source = ((given, "--period") if given else (sdo, "SDO 0x1006") if sdo
                      else (stamps, "SYNC time stamps") if stamps else (None, "default"))
    out: dict[str, Any] = {"period_s": chosen, "source": source, "sync_stamps_s": stamps,
                           "sdo_period_s": sdo}
    if (stamps and chosen and source != "SYNC time stamps" and not lockstep
            and abs(stamps - chosen) > CLOCK_TOLERANCE * chosen):
        named = "--period" if source == "--period" else "the log's SDO 0x1006"
        how = ("--period" if source == "--period" else
               "the log's SDO 0x1006's (give --period to choose)")
        out["warning"] = (f"the SYNC time stamps are {stamps * 1e3:.4g} ms apart but "
                          f"{named} gives a period of {chosen * 1e3:.4g} ms: the table uses "
                          f"{how}")
    return out


def _stamp_period(rows: Any) -> float | None:
    """The median SYNC period from the rows' bus times (a lost SYNC's row has none; a
    counter step of k periods counts k) to the microsecond, None with fewer than 3
    intervals."""
    if not len(rows):
        return None
    bt = np.frombuffer(rows.bus_time, dtype=float)
    run = np.frombuffer(rows.run, dtype=float)
    k = np.flatnonzero(np.isfinite(bt))
    if len(k) < 4:
        return None
    steps = np.diff(k)
    same = run[k[1:]] == run[k[:-1]]
    d = np.diff(bt[k])[same] / steps[same]
    d = d[d > 0]
    if len(d) < 3:
        return None
    med = float(np.median(d))            # to the microsecond: candump's stamps' resolution
    return round(med * 1e6) / 1e6 if med >= 1e-5 else med


def _counting_order(messages: Iterable[can.Message], dec: RowAssembler
                    ) -> Iterator[can.Message]:
    """`messages` unchanged, each counted by `dec.order` (in log order) on the way."""
    for m in messages:
        dec.order(m)
        yield m



def trace_from_log(path: str | Path, node_id: int | None = None, period_s: float | None = None,
                   counts_per_rev: int | None = None,
                   issues: Any = None, fmt: str | None = None) -> Trace:
    """The signal table of a log (for the HUMS, the gap diagnosis, `bench decode`): candump
    ``.log`` or any other format of LOG_FORMATS (`bench.bus.logread.read_frames`).

    Bad lines are skipped, counted and the first ones listed in ``trace.meta["issues"]``
    (and collected in `issues` when given: a list or a `LogIssues`); the rest of the log
    is kept. A log whose frames are out of time order (``meta["out_of_order"]``) is
    decoded again in time-stamp order (``meta["sorted_by_time"]``): every stamp of a log
    is the time its frame was on the bus, taken on one clock, so the stamps keep the bus
    order that an edited or merged file lost. BenchError when no SYNC period is found.
    `path` ``-`` is standard input; `fmt` names the format (default: the suffix,
    candump -L on standard input; `bench.bus.logread.source_format`)."""
    found = LogIssues(100) if issues is None else issues
    first = _Counted(found)
    try:
        tr = trace_from_messages(read_frames(path, first, raw=True, fmt=fmt), node_id, period_s,
                                 counts_per_rev, found, source=str(path),
                                 stop_on_disorder=True)
    except _OutOfOrder:        # read it all again, in time-stamp order
        tr = trace_from_messages(read_frames(path, _Counted(found, skip=first.seen), fmt=fmt),
                                 node_id,
                                 period_s, counts_per_rev, found, source=str(path),
                                 sort_by_time=True)
    if is_stdin(path):
        path = "standard input"
    if not len(tr):
        n = len(found)
        first_issue = next(iter(found), None)
        raise BenchError(f"{path}: nothing to decode: {tr.meta['frames']} frames, no SYNC "
                         f"frame, so no control period"
                         + (f"; {n} bad lines ({first_issue})" if n else ""))
    _check_layout(tr, path)
    if not set(tr.meta["row_frames_seen"]) - {"ECU_Setpoint"}:
        raise BenchError(f"{path}: {len(tr)} SYNC periods but not one frame of node "
                         f"0x{tr.meta['node_id']:02X} (its TPDOs, the RPDO to it): the node "
                         "was not on the bus, or the log is of another node (--node-id)")
    return tr


MISFIT_SHARE = 0.02
"""The share of the frames on the node's row-frame ids (its PDOs, the ECU's set-point)
that may not fit the DBC's layout before a log is refused as not this node's: a few
frames damaged on the bus are counted and said; a log where more do not fit is another
device's on the same COB-IDs, or another layout."""


def _check_layout(tr: Trace, path: Any) -> None:
    """BenchError when more than MISFIT_SHARE of the frames on the node's row-frame ids
    do not fit the DBC (a length no layout of the message has, a value outside its
    signal's range): their numbers would be garbage, summed into usage and graded."""
    misfit = tr.meta.get("misfit_frames") or {}
    total = int(tr.meta.get("row_id_frames") or 0)
    bad = sum(misfit.values())
    if total and bad > MISFIT_SHARE * total:
        what = ", ".join(f"{k} {v}" for k, v in sorted(misfit.items()))
        raise BenchError(f"{path}: not this node's layout: {bad} of the {total} frames on "
                         f"node 0x{tr.meta['node_id']:02X}'s PDO and set-point ids do not fit "
                         f"the DBC ({what}; a length or a value it does not allow): another "
                         "device's log on the same COB-IDs? Decode it with its own DBC "
                         "($EMA_BENCH_DBC_DIR) or the right --node-id")


class _Counted:
    """Passes issues on to `target`, skipping the first `skip` (already passed on by an
    earlier read of the same file), and counts them."""

    def __init__(self, target: Any, skip: int = 0) -> None:
        self.target, self.skip, self.seen = target, skip, 0

    def append(self, issue: LogIssue) -> None:
        if self.seen >= self.skip:
            self.target.append(issue)
        self.seen += 1



TABLE_SUFFIXES = TRACE_FORMATS
"""The trace tables a log may also be (`bench.signals.tables.TRACE_FORMATS`)."""
LOG_INTEGRITY = ("sync_gaps", "sync_recovered", "missing_frames", "duplicate_frames",
                 "replaced_frames", "out_of_order", "sorted_by_time", "nan_blocks")
"""Metadata kept from a decoded log or an imported table: what it lost or repeated."""
SAMPLING = ("sample_period_s", "resampled", "split")
"""Metadata kept from an imported table: its own sample period, whether it was
resampled, and the key values it was split by (`bench import --split-by`)."""


def _decoded(path: str | Path, fmt: str | None) -> Trace:
    return trace_from_log(path, fmt=fmt)


def _table(path: str | Path, fmt: str | None) -> Trace:
    return Trace.load(path)


LOG_READERS: dict[str, Callable[[str | Path, str | None], Trace]] = {
    **{s: _decoded for s in LOG_FORMATS}, **{s: _table for s in TABLE_SUFFIXES}}
"""Log suffix -> its loader, as python-can's ``can.io.MESSAGE_READERS``: a bus log of
LOG_FORMATS decoded through the DBC (python-can's readers underneath, candump ``.log``
by the tolerant line reader), or a trace table (`bench.signals.trace.Trace.load`)."""


def known_logs() -> str:
    """The log suffixes in words, for a message."""
    return (", ".join(f"{s} ({d})" for s, d in LOG_FORMATS.items())
            + f" (also {'/'.join(COMPRESSIONS)}-compressed), or a trace "
            + ", ".join(TABLE_SUFFIXES))


def load_trace(path: str | Path, fmt: str | None = None, measured: bool = False) -> Trace:
    """The one log loader: a bus log or a saved trace table as a Trace, by the loader of
    its suffix (`LOG_READERS`; ``-``: standard input, candump -L unless `fmt` names the
    format; `fmt` also where the suffix does not say it); BenchError in one line naming
    the file, and for an unknown suffix the known ones. `measured`: only the measured
    columns (simulation truth dropped) and the metadata a real log could carry (the
    command fundamental, LOG_INTEGRITY, SAMPLING), as the gap and calibration read."""
    if is_stdin(path) or fmt:
        tr = trace_from_log(path, fmt=fmt)
    else:
        path = Path(path)
        if not path.exists():
            raise BenchError(f"no such file: {path}")
        if path.is_dir():
            raise BenchError(f"{path} is a directory, not a log (name the log files in it)")
        suffix, comp = log_suffixes(path)
        if suffix not in LOG_READERS or comp and suffix not in LOG_FORMATS:
            name = suffix + comp
            raise BenchError(f"{path}: unknown log format {name or '(no suffix)'!r} (use "
                             f"{known_logs()})")
        tr = LOG_READERS[suffix](path, None)
    tr.meta.setdefault("source", str(path))
    return _measured(tr, path) if measured else tr


def _measured(tr: Trace, path: str | Path) -> Trace:
    meta: dict[str, Any] = {"source": str(path)}
    meta.update({k: v for k, v in (tr.meta or {}).items() if k in LOG_INTEGRITY})
    meta.update({k: v for k, v in (tr.meta or {}).items() if k in SAMPLING})
    f0 = (tr.meta or {}).get("fundamental_hz")
    if isinstance(f0, (int, float)):
        meta["fundamental_hz"] = float(f0)
    out = tr.measured()
    out.meta = meta
    return out
