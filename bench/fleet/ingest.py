"""`bench fleet ingest PATH...`: logs into the fleet store, idempotent and resumable.

PATHs are files, directories (searched recursively for LOG_SUFFIXES, a bus log also
.gz/.xz/.bz2-compressed) and globs (``**``
allowed); a PATH that is neither a file nor a directory (a FIFO, ``/dev/null``) is
refused. Each file is keyed by the digest of its content (`digest`: sha256 of its lines
in a canonical form for the text formats, of its bytes for the others): digests already
in the store are skipped before any work, so the same log twice is stored once, under
whatever name, with whatever line ends or blank lines. The rest are analysed on the worker pool (`bench.runtime.workers.run_all`):
decoded (`bench.bus.logs.load_trace`: candump through the DBC, or a trace table) and
graded by the HUMS report's own analysis (`bench.hums.report.analyse`: the indexes of
eq. 6.4-6.7 against the monitoring model driven by the log's set-points, and the verdict
of `bench.hums.verdict.judge`), without the per-log fused RUL (a ground test is too
short for it; the fleet's RUL is over days, `bench.fleet.status`). Results are written
by this process in batches of whole runs, one transaction each (`Store.write`): a
killed ingest loses only its open batch, and the next ingest redoes exactly those logs.
A log that cannot be read, dated or graded is stored in ``failures`` with its file name
and one-line error (and skipped next time, by digest) and the ingest goes on: every
per-log step (digest, decoding, metadata, run time, grading) runs inside the per-log
error handling, in this process and in the workers.

The actuator id, in order: the log's own (``actuator_id``, ``actuator_serial`` or
``serial_number`` in the decoded trace's metadata: the 0x1018 serial number the ECU
reads by SDO, which the log decoder reports; "unknown" and the default 0 name no
actuator), else ``--actuator``, else the name of the file's parent directory.
The run time: the first time stamp of a bus log (the bus clock, UTC; a stamp before
ABSOLUTE_AFTER is relative, as python-can reads an ASC log), else a trace
table's ``run_time``/``start_time`` metadata (epoch seconds or ISO 8601; an ISO time
without a zone is UTC, as ``fleet status --as-of`` reads it), else the file's
modification time. A run time outside the years 1970-9999 is the log's failure.
"""

from __future__ import annotations

import datetime as dt
import glob
import hashlib
import math
import os
import re
import stat
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.bus.logread import DECOMPRESS_ERRORS, cannot_decompress
from bench.bus.logs import TABLE_SUFFIXES
from bench.bus.logwrite import COMPRESSIONS, LOG_FORMATS, log_suffixes
from bench.signals.textlines import COMPRESSED
from bench.signals.trace import Trace

LOG_SUFFIXES = (*LOG_FORMATS, *TABLE_SUFFIXES)
"""What `bench.bus.logs.load_trace` reads: the bus log formats (also compressed,
`is_log_name`) and the trace table formats."""
ABSOLUTE_AFTER = 1e9
"""Epoch seconds (a time in 2001) before which a log's first time stamp is relative to its
start, not a time of day."""


def is_log_name(path: Path) -> bool:
    """`path` is named as a file `load_trace` reads (LOG_SUFFIXES; a bus log also under a
    compression suffix)."""
    fmt, comp = log_suffixes(path)
    return fmt in LOG_FORMATS if comp else fmt in LOG_SUFFIXES


BATCH_RUNS = 64
BATCH_S = 5.0
"""A batch is committed after BATCH_RUNS results (``$BENCH_FLEET_BATCH`` overrides it)
or BATCH_S seconds, whichever comes first."""


HOT_K = 400.0
"""`time_hot_s` counts the winding above 400 K (127 degC): the usage monitor's 10 K
temperature bin edge nearest below the 403 K (130 degC) limit of class B insulation."""


def usage_columns(trace: Trace) -> dict[str, Any]:
    """The usage of one run (`bench.usage.usage_of_trace`, docs/usage.md), by the schema's
    usage column names (`schema.USAGE_COLUMNS`); a value the run cannot give (L10 of a
    run without load, a signal it lacks) is NULL."""
    from bench.usage.accumulator import usage_of_trace
    from bench.usage.settings import TEMP_EDGES_K
    u = usage_of_trace(trace)
    d = u.as_dict()
    hot = None if "temperature_time_s" in u.not_available else sum(
        float(t) for lo, t in zip(TEMP_EDGES_K[:-1], u.temperature_time_s, strict=True)
        if lo >= HOT_K)
    row = {"travel_m": d["nut_travel_m"], "screw_revs": d["screw_revolutions"],
           "reversals": int(d["reversals"]) if math.isfinite(d["reversals"]) else None,
           "equivalent_load_n": d["fm_n"],
           "life_consumed": d["life_consumed"], "i2t_a2s": d["i2t_a2s"],
           "time_hot_s": hot}
    return {k: (v if v is None or isinstance(v, int) or math.isfinite(v) else None)
            for k, v in row.items()}


# --- finding the files ---------------------------------------------------------------------

def expand(paths: Iterable[str]) -> list[Path]:
    """The log files named by `paths` (files, directories searched recursively, globs),
    each once, sorted; BenchError naming a path that matches nothing, or that is no
    regular file or directory (a FIFO, a device: reading one would hang or read
    nothing)."""
    found: set[Path] = set()
    for p in paths:
        hits = [Path(h) for h in glob.glob(p, recursive=True)] if glob.has_magic(p) \
            else [Path(p)]
        if not any(os.path.lexists(h) for h in hits):
            raise BenchError(f"no such file or directory: {p}")
        for h in hits:
            if h.is_dir():
                logs = {f for f in h.rglob("*") if f.is_file() and is_log_name(f)}
                if not logs and not glob.has_magic(p):
                    raise BenchError(f"{p}: a directory with no log in it (none of "
                                     f"{', '.join(LOG_SUFFIXES)}, a bus log also "
                                     f"{'/'.join(COMPRESSIONS)}-compressed; searched "
                                     "recursively)")
                found.update(logs)
            elif h.is_file():
                found.add(h)
            elif not glob.has_magic(p):
                raise BenchError(f"{p}: not a log file or a directory ({_kind(h)}); give "
                                 "log files, directories or globs")
    return sorted(found)


def _kind(p: Path) -> str:
    """What a path that is no regular file or directory is, in words."""
    try:
        mode = os.stat(p).st_mode
    except OSError:
        return "a broken link"
    return ("a FIFO" if stat.S_ISFIFO(mode) else "a character device" if stat.S_ISCHR(mode)
            else "a block device" if stat.S_ISBLK(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "not a regular file")


TEXT_SUFFIXES = (".log", ".csv")
"""The text formats whose digest is of their lines in a canonical form."""
_SPACES = re.compile(rb"[ \t\r\f\v]+")
_LINE_ENDS = re.compile(rb" ?\n[ \n]*")


def _canonical(block: bytes, collapse: bool) -> bytes:
    """Whole lines in a canonical form: blanks around a line and blank lines dropped,
    every line ended by one LF; with `collapse`, each run of blanks inside a line is one
    space (candump's fields), else only the blanks at the line ends go (a CSV's text)."""
    if collapse:
        text = _SPACES.sub(b" ", block)
    else:
        text = re.sub(rb"[ \t\r\f\v]+(?=\n)", b"", block.replace(b"\r\n", b"\n"))
    text = _LINE_ENDS.sub(b"\n", text).strip(b" \n")
    return text + b"\n" if text else b""


def _unreadable(path: Path, exc: Exception) -> str:
    """Why a log's digest could not be taken, in words."""
    fmt, comp = log_suffixes(path)
    if comp and fmt in LOG_FORMATS:
        return cannot_decompress(comp, exc)
    return f"cannot be read ({getattr(exc, 'strerror', None) or exc})"


def digest(path: str | Path) -> str:
    """The run's identity (hex sha256): of a candump log's or a CSV table's lines in a
    canonical form (`_canonical`: CRLF or LF, blanks at the ends of lines, blank lines
    and, in a candump log, the spacing between fields do not count), of the file's bytes
    for the other formats. A file already in the canonical form has the digest of its
    bytes (the digest of stores written before)."""
    h = hashlib.sha256()
    suffix, comp = log_suffixes(path)
    if comp and suffix not in LOG_FORMATS:
        suffix = comp
    opener = COMPRESSED.get(comp) if suffix in LOG_FORMATS else None
    with (opener or open)(path, "rb") as f:
        if suffix not in TEXT_SUFFIXES:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
            return h.hexdigest()
        rest = b""
        for block in iter(lambda: f.read(1 << 20), b""):
            block = rest + block
            cut = block.rfind(b"\n") + 1
            rest = block[cut:]
            h.update(_canonical(block[:cut], suffix == ".log"))
        h.update(_canonical(rest, suffix == ".log"))
    return h.hexdigest()


# --- one log ---------------------------------------------------------------------------------

NO_ID = ("", "unknown", "0")
"""Serial numbers that name no actuator: none in the log ("unknown": a node without
0x1018, or a log without the ECU's start-up) and 0, the plant's default when no
``--serial`` was given (every such plant would otherwise be one actuator)."""


def actuator_id(trace: Trace | None, path: Path, given: str | None) -> str:
    """The actuator id (module docstring: the log's, else `given`, else the parent
    directory's name)."""
    if trace is not None:
        for key in ("actuator_id", "actuator_serial", "serial_number"):
            v = trace.meta.get(key)
            if v is not None and str(v) not in NO_ID:
                return str(v)
    if given:
        return given
    return path.resolve().parent.name or "unknown"


def run_time(path: Path, trace: Trace | None) -> float:
    """The run's start, epoch seconds (module docstring)."""
    fmt = log_suffixes(path)[0]
    if fmt in LOG_FORMATS:
        from bench.bus.logread import read_frames
        for _, msg in zip(range(1000), read_frames(path), strict=False):
            ts = float(msg.timestamp)
            if ts > 0 and math.isfinite(ts):
                if ts >= ABSOLUTE_AFTER:
                    return ts
                break
    elif trace is not None:
        for key in ("run_time", "start_time"):
            v = trace.meta.get(key)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                return float(v)
            if isinstance(v, str):
                try:
                    return utc_seconds(v)
                except ValueError:
                    pass
    return path.stat().st_mtime


def utc_seconds(text: str) -> float:
    """An ISO 8601 time as epoch seconds, UTC when it names no zone (the rule of
    ``fleet status --as-of``); ValueError if it is none."""
    t = dt.datetime.fromisoformat(text.strip())
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.UTC)
    return t.timestamp()


def run_datetime(seconds: float) -> dt.datetime:
    """A run time (epoch seconds) as the store's naive UTC TIMESTAMP; ValueError naming
    the value when it is no date of the years 1970-9999 (a log stamped 1e12 s ahead)."""
    try:
        when = dt.datetime.fromtimestamp(seconds, dt.UTC)
    except (ValueError, OverflowError, OSError):
        when = None
    if when is None or when.year < 1970:
        raise ValueError(f"its run time {seconds:.6g} s is no date of the years 1970-9999 "
                         "(a first time stamp far off: the bus clock?)")
    return when.replace(tzinfo=None)


def _mode(trace: Trace) -> int | None:
    if "mode" not in trace:
        return None
    m = np.asarray(trace["mode"], dtype=float)
    m = m[np.isfinite(m)]
    return int(np.bincount(m.astype(int)).argmax()) if len(m) else None


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def ingest_one(job: tuple[str, str, str | None]) -> dict[str, Any]:
    """Worker: one log (path, digest, --actuator) -> its row, or its failure (any error
    of any step, the file named)."""
    path_s, dig, given = job
    path = Path(path_s)
    trace: Trace | None = None
    try:
        from bench.bus.logs import load_trace
        trace = load_trace(path)
        return _row(path, dig, given, trace)
    except Exception as exc:  # noqa: BLE001 - any failure is the log's, recorded
        return failure(path, dig, exc, _safe_id(trace, path, given))


def failure(path: Path, dig: str, exc: BaseException, ident: str) -> dict[str, Any]:
    """The failure row of one log: its file, its actuator and the error in one line."""
    msg = " ".join(str(exc).split()) or type(exc).__name__
    kind = "" if isinstance(exc, BenchError) else f"{type(exc).__name__}: "
    return {"digest": dig, "path": str(path), "error": f"{kind}{msg}"[:500],
            "actuator_id": ident}


def _safe_id(trace: Trace | None, path: Path, given: str | None) -> str:
    try:
        return actuator_id(trace, path, given)
    except Exception:  # noqa: BLE001 - a failure row still gets one
        return given or "unknown"


def _row(path: Path, dig: str, given: str | None, trace: Trace) -> dict[str, Any]:
    """The stored row of one decoded log: graded by the HUMS report's analysis."""
    from bench.hums.report import analyse
    when = run_datetime(run_time(path, trace))
    a = analyse(trace, path.name, rul=False)
    tr = a.trace
    row: dict[str, Any] = {
        "digest": dig, "actuator_id": actuator_id(trace, path, given), "run_time": when,
        "path": str(path.resolve()), "bytes": path.stat().st_size, "rows": len(tr),
        "duration_s": len(tr) * tr.dt if len(tr) > 1 else 0.0, "mode": _mode(tr),
        "f0_hz": _finite(a.f0_hz), "verdict": a.verdict.name, "level": int(a.verdict.level),
        "reasons": "; ".join(a.reasons), "notes": "; ".join(a.notes)}
    from bench.fleet.schema import INDEX_COLUMNS
    for c in INDEX_COLUMNS:
        row[c] = _finite(float(getattr(a.indexes, c)))
    row.update(usage_columns(tr))
    return row


# --- the ingest --------------------------------------------------------------------------------

@dataclass
class IngestResult:
    files: int
    skipped: int
    stored: int
    failed: int
    elapsed_s: float
    failures: list[tuple[str, str]]
    failed_before: int = 0      # of `skipped`: logs already in `failures`, not retried


def ingest(paths: Iterable[str], db: str | Path, workers: int | None = None,
           scheduler: str | None = None, actuator: str | None = None,
           progress: bool = True) -> IngestResult:
    """Ingest every log `paths` names into the store `db` (module docstring)."""
    from bench.fleet.store import Store
    t0 = time.perf_counter()
    files = expand(paths)
    with Store(db) as store:
        known, failed = store.known(), store.failed()
        jobs = []
        again = 0
        seen: set[str] = set()
        batch = _Batch(store)
        try:
            for f in files:
                unreadable: Exception | None = None
                try:
                    d = digest(f)
                except DECOMPRESS_ERRORS as exc:     # unreadable: a failure of its own
                    d = "unreadable:" + hashlib.sha256(str(f.resolve()).encode()).hexdigest()
                    unreadable = exc
                again += d in failed
                if d in known or d in seen:
                    continue
                seen.add(d)
                if unreadable is None:
                    jobs.append((str(f), d, actuator))
                else:
                    batch.add(failure(f, d, BenchError(_unreadable(f, unreadable)),
                                      actuator or "unknown"))
            run_jobs(ingest_one, jobs, workers, progress, scheduler, batch.add,
                     label=lambda job: str(job[0]))
        finally:
            batch.flush()
    fails = [(r["path"], r["error"]) for r in batch.done if "error" in r]
    return IngestResult(len(files), len(files) - len(batch.done), batch.stored - len(fails),
                        len(fails), time.perf_counter() - t0, fails, again)


class _Batch:
    """Results gathered and written a batch at a time (one transaction each)."""

    def __init__(self, store: Any) -> None:
        self.store, self.open, self.done = store, [], []   # type: ignore[var-annotated]
        self.stored = 0
        self.t_last = time.monotonic()
        self.size = max(1, int(os.environ.get("BENCH_FLEET_BATCH") or BATCH_RUNS))

    def add(self, result: dict[str, Any]) -> None:
        self.open.append(result)
        if len(self.open) >= self.size or time.monotonic() - self.t_last > BATCH_S:
            self.flush()

    def flush(self) -> None:
        if self.open:
            self.stored += self.store.write(self.open)
            self.done.extend({"path": r["path"], "error": r["error"]} if "error" in r
                             else {"path": r["path"]} for r in self.open)
            self.open = []
        self.t_last = time.monotonic()


CHUNK_LOGS = 16
"""Logs per Dask task at most: a log costs ~0.06 s of CPU to ingest or to synthesise
(docs/performance.md, "Fleet"), so a task of 16 lasts ~1 s, and Dask's per-task cost
(scheduling, transfer: a few ms) is a small share of it."""


def chunk_size(n_jobs: int, workers: int | None) -> int:
    """Logs per task: CHUNK_LOGS, but at least 8 tasks per worker (a worker must not wait
    idle for another's last long task, and a killed worker costs little)."""
    per = max(1, workers or 2)
    return max(1, min(CHUNK_LOGS, -(-n_jobs // (8 * per))))


def run_jobs(fn: Any, jobs: list[Any], workers: int | None, progress: bool,
             scheduler: str | None, on_result: Any = None, desc: str = "fleet ingest",
             unit: str = "log", label: Any = None) -> list[Any]:
    """`bench.runtime.workers.run_all` (Dask: a LocalCluster on 127.0.0.1 of `workers` processes,
    or the cluster at `scheduler`), with `on_result` called as each job finishes; the
    jobs go to the workers `chunk_size` at a time; `label(job)` names a job that fails."""
    from bench.runtime.workers import run_all
    return run_all(fn, jobs, workers, progress, desc=desc, unit=unit, on_result=on_result,
                   scheduler=scheduler, chunk=chunk_size(len(jobs), workers), label=label)
