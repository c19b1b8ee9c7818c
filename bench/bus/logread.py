"""Log files -> frames, for `bench.bus.logs` (decode, HUMS report, gap) and `bench replay`:
`read_frames` reads candump ``.log`` with the tolerant line reader below and the other
formats of `bench.bus.logwrite.LOG_FORMATS` (``.asc``, ``.blf``, ``.trc``, ``.mf4``)
through `can.LogReader`; each format also under ``.gz``, ``.xz`` or ``.bz2``
(`bench.bus.logwrite.COMPRESSIONS`), decompressed as it is read.

The format is ``candump -L`` (python-can's `CanutilsLogWriter`/`CanutilsLogReader`):
``(1700000000.123456) vcan0 190#E8030000400 R``. `read_log` streams it line by line and,
unlike `CanutilsLogReader` (which stops at the first bad line), reports each truncated
or corrupted line with its number and keeps the rest; bad lines are counted and only the
first ones kept (`LogIssues`), and a line is read MAX_LINE characters at most, so memory
stays bounded whatever the file holds.

A log may come on standard input (path ``-``: ``candump -L can0 | bench decode -``):
read once into a spooled buffer (memory up to STDIN_SPOOL_BYTES, then an unnamed
temporary file), candump -L unless another format is named (`source_format`). A line of
candump's default output (``  can0  190   [6]  7E 00 ...``, no ``-L``) is a bad line that
says to record with ``candump -L``.
"""

from __future__ import annotations

import atexit
import gc
import io
import logging
import lzma
import re
import shutil
import sys
import tempfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from bench import BenchError, allow_mf4_import
from bench.bus.logwrite import LOG_FORMATS, log_format, log_suffixes
from bench.signals.textlines import COMPRESSED

LINE = re.compile(r"^\((?P<ts>\d+(?:\.\d*)?)\)\s+(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})"
                  r"#(?P<fd>#[0-9A-Fa-f])?(?P<data>[0-9A-Fa-f]*|R\d{0,2})(?:\s+(?P<dir>[RT]))?$")
FD_LENGTHS = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64}

PLAIN_CANDUMP = re.compile(r"^\s*(\(\d+(\.\d*)?\)\s+)?\S+\s+[0-9A-Fa-f]{3,8}\s+\[\d{1,2}\]")
"""A line of candump's default output (``candump can0``, optionally with ``-t a``)."""
NOT_L = "candump's default output, not candump -L: record the log with `candump -L`"
STDIN = "-"
"""The path that means standard input."""
DECOMPRESS_ERRORS = (EOFError, OSError, lzma.LZMAError, zlib.error)
"""What a damaged or truncated .gz, .xz or .bz2 stream raises as it is read."""
STDIN_SPOOL_BYTES = 64 << 20
"""Standard input held in memory up to this size, then in an unnamed temporary file."""

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


def _match(s: str) -> re.Match[str]:
    """The candump -L fields of a stripped line (ValueError saying why it is not one)."""
    m = LINE.match(s)
    if m is None:
        if PLAIN_CANDUMP.match(s):
            raise ValueError(NOT_L)
        if s.startswith("(") and ")" not in s:
            raise ValueError("truncated timestamp")
        if "#" not in s:
            raise ValueError("no frame (expected ID#DATA)")
        raise ValueError("not a candump -L frame")
    return m


def parse_line(text: str) -> can.Message:
    """One candump -L line as a Message (ValueError with the reason if it is not one)."""
    m = _match(text.strip())
    ident, data, fd = m["id"], m["data"], m["fd"]
    can_id = int(ident, 16)
    ext = len(ident) == 8
    if not ext and can_id > 0x7FF:
        raise ValueError(f"standard id 0x{can_id:X} above 0x7FF")
    if ext and can_id & 0x20000000:     # error frame as written by CanutilsLogWriter
        return can.Message(timestamp=float(m["ts"]), is_error_frame=True)
    if can_id > 0x1FFFFFFF:             # candump writes no other flag into the id
        raise ValueError(f"extended id 0x{can_id:08X} above 0x1FFFFFFF")
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


def read_log(path: str | Path, issues: Any = None, raw: bool = False
             ) -> Iterator[Any]:
    """The frames of a candump log (``-``: standard input), streamed; bad lines go to
    `issues` (anything with ``append``, e.g. a list or a `LogIssues`; line numbers from
    1). BenchError when the file does not exist or cannot be read. With `raw`, a
    well-formed line of a classic data frame with an 11-bit id (nearly every line of a
    rig's log) comes as the tuple (time stamp, id, payload, is_rx) of `fast_frame`, for
    `bench.bus.rows.RowAssembler.feed_frame`; every other line as a can.Message."""
    comp = "" if is_stdin(path) else log_suffixes(path)[1]
    lineno = 0
    with open_log_text(path) as fh:
        try:
            for lineno, line in enumerate(_lines(fh), start=1):
                if line is None:
                    if issues is not None:
                        issues.append(LogIssue(lineno, f"line longer than {MAX_LINE} "
                                                       "characters", ""))
                    continue
                if raw:
                    frame = fast_frame(line)
                    if frame is not None:
                        yield frame
                        continue
                if not line.strip():
                    continue
                try:
                    yield parse_line(line)
                except ValueError as exc:
                    if issues is not None:
                        issues.append(LogIssue(lineno, str(exc), line.rstrip("\r\n")))
        except DECOMPRESS_ERRORS as exc:
            if not comp:
                raise
            raise BenchError(f"{path}: {cannot_decompress(comp, exc, lineno)}") from None


def cannot_decompress(comp: str, exc: BaseException, after_line: int | None = None,
                      what: str = "file") -> str:
    """A damaged or cut `comp` stream, in words (the caller names the file)."""
    at = f" after line {after_line}" if after_line is not None else ""
    return f"cannot decompress{at} ({_reason(exc)}): is it a complete {comp} {what}?"


def _decompress_into(src: Any, comp: str, out: Any, name: str, what: str) -> Any:
    """`src` (a path or a binary file) decompressed from `comp` into the binary file
    `out`, returned at its start; `out` closed and a BenchError naming `name` when the
    stream is damaged."""
    try:
        with COMPRESSED[comp](src, "rb") as stream:
            shutil.copyfileobj(stream, out, 1 << 20)
    except DECOMPRESS_ERRORS as exc:
        out.close()
        raise BenchError(f"{name}: {cannot_decompress(comp, exc, what=what)}") from None
    out.seek(0)
    return out


MAGIC = {b"\x1f\x8b": ".gz", b"\xfd7zXZ\x00": ".xz", b"BZh": ".bz2"}
"""The first bytes of a gzip, xz and bzip2 stream: a compressed log on standard input
(`cat run.log.gz | bench decode -`) is decompressed as a named one is."""


def _decompress_spool(buf: Any) -> Any:
    """`buf` (a spooled copy of standard input), decompressed into a new spool when it
    starts with a compression's magic bytes (MAGIC); BenchError when that stream is
    damaged."""
    buf.seek(0)
    head = buf.read(6)
    comp = next((c for m, c in MAGIC.items() if head.startswith(m)), None)
    if comp is None:
        return buf
    buf.seek(0)
    try:
        return _decompress_into(buf, comp, tempfile.SpooledTemporaryFile(
            max_size=STDIN_SPOOL_BYTES), "standard input", "stream")
    finally:
        buf.close()


def is_stdin(path: Any) -> bool:
    return isinstance(path, (str, Path)) and str(path) == STDIN


_STDIN: list[tuple[Any, Any]] = []
"""(the stdin object read, its content as a spooled binary file)."""


@atexit.register
def _close_stdin_spool() -> None:
    for _, buf in _STDIN:
        buf.close()
    _STDIN.clear()


def stdin_buffer() -> Any:
    """Standard input read to its end into a spooled binary file (once per stdin
    object), at its start."""
    stdin = sys.stdin
    buf = _STDIN[0][1] if _STDIN and _STDIN[0][0] is stdin else None
    if buf is None:
        for _, old in _STDIN:
            old.close()
        _STDIN.clear()
        buf = tempfile.SpooledTemporaryFile(max_size=STDIN_SPOOL_BYTES)
        src = getattr(stdin, "buffer", None)
        while True:
            block = src.read(1 << 20) if src is not None else stdin.read(1 << 20).encode()
            if not block:
                break
            buf.write(block)
        buf = _decompress_spool(buf)
        _STDIN.append((stdin, buf))
    buf.seek(0)
    return buf


@contextmanager
def open_log_text(path: str | Path) -> Iterator[Any]:
    """A log as text lines (undecodable bytes replaced): the file, or standard input."""
    if is_stdin(path):
        fh = io.TextIOWrapper(stdin_buffer(), errors="replace", newline="")
        try:
            yield fh
        finally:
            fh.detach()                 # the buffer stays open for another read
        return
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such log: {path}")
    comp = log_suffixes(path)[1]
    try:
        f = (COMPRESSED[comp](path, "rt", errors="replace", newline="") if comp
             else path.open("r", errors="replace", newline=""))
    except OSError as exc:
        raise BenchError(f"cannot read {path}: {exc.strerror or exc}") from None
    with f:
        yield f


def source_format(path: str | Path, fmt: str | None = None) -> str:
    """The log format (a LOG_FORMATS suffix) of `path`: `fmt` when given (``log``,
    ``.asc``...), candump -L for standard input, else the file's suffix (BenchError
    naming the formats and ``--format``)."""
    if fmt:
        suffix = "." + fmt.lower().lstrip(".")
        if suffix not in LOG_FORMATS:
            raise BenchError(f"--format {fmt}: unknown log format (use one of "
                             f"{', '.join(s[1:] for s in LOG_FORMATS)})")
        return suffix
    if is_stdin(path):
        return ".log"
    try:
        return log_format(path, compressed=True)
    except BenchError as exc:
        raise BenchError(f"{exc}; name the format with --format") from None


_HEX_IDS: dict[str, int] = {}
"""3-digit hex ids seen by `fast_frame` -> their value (at most 4096 entries)."""
_HEX = frozenset("0123456789abcdefABCDEF")


def fast_frame(line: str) -> tuple[float, int, bytes, bool] | None:
    """A candump -L line of a classic data frame with an 11-bit id, e.g.
    ``(1700000000.123456) can0 190#E803000040 T``, as (time stamp, id, payload, is_rx):
    what `parse_line` gives (its Message's fields), at a fraction of the cost. None for
    any other line, well-formed or not (`parse_line` then says what it is)."""
    p = line.split()
    if len(p) == 4:
        rx = p[3]
        if rx != "T" and rx != "R":
            return None
    elif len(p) != 3:
        return None
    ts, frame = p[0], p[2]
    if ts[0] != "(" or ts[-1] != ")" or frame[3:4] != "#" or not line.isascii():
        return None
    whole, _, part = ts[1:-1].partition(".")
    if not whole.isdigit() or part and not part.isdigit():
        return None
    ident = frame[:3]
    cid = _HEX_IDS.get(ident)
    if cid is None:
        if not _HEX.issuperset(ident):
            return None
        cid = _HEX_IDS[ident] = int(ident, 16)
    data = frame[4:]
    if cid > 0x7FF or len(data) > 16 or data[:1] in ("R", "#"):
        return None
    try:
        payload = bytes.fromhex(data)
    except ValueError:                           # odd length or not hex: parse_line says
        return None
    return float(ts[1:-1]), cid, payload, len(p) == 3 or p[3] != "T"


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


def read_frames(path: str | Path, issues: Any = None, raw: bool = False,
                fmt: str | None = None) -> Iterator[Any]:
    """The frames of a log in any of LOG_FORMATS (``-``: standard input), in file order,
    streamed; the format from `fmt`, else the suffix (`source_format`). A candump ``.log``
    goes through the tolerant `read_log` (python-can's reader stops at the first bad
    line; a rig's log must lose only its bad lines); ``.asc``, ``.blf``, ``.trc`` and
    ``.mf4`` through python-can's readers, whose warnings about records they skipped go
    to `issues` (numbered by the frame they follow). BenchError in one line for an
    unknown format, a missing file, or a file python-can cannot read on (damaged: the
    error names the frames read before it). `raw`: a candump log's plain frames as
    tuples (`read_log`)."""
    suffix = source_format(path, fmt)
    if suffix == ".log":
        yield from read_log(path, issues, raw)
        return
    if not is_stdin(path) and not Path(path).is_file():
        raise BenchError(f"no such log: {path}")
    n = 0
    with _quiet(issues, lambda: n) as failed:
        try:
            reader = _reader(path, suffix)
            with reader:
                for msg in reader:
                    n += 1
                    yield msg
        except BenchError:
            raise
        except Exception as exc:  # noqa: BLE001 - any reader's parse error, said in one line
            failed.append(_reason(exc))
        if failed:
            raise BenchError(f"{path}: cannot read this {LOG_FORMATS[suffix]} log "
                             f"(python-can) after {n} frames: {failed[0]}")


def _reader(path: str | Path, suffix: str) -> Any:
    """python-can's reader of format `suffix` on the file `path` or standard input."""
    if suffix == ".mf4":
        allow_mf4_import()
    classes = {".asc": can.ASCReader, ".blf": can.BLFReader, ".trc": can.TRCReader,
               ".mf4": can.MF4Reader}
    if not is_stdin(path):
        fmt, comp = log_suffixes(path)
        if not comp:
            if fmt == suffix:
                return can.LogReader(path)
            return classes[suffix](str(path))
        if suffix in (".asc", ".trc"):
            return classes[suffix](io.TextIOWrapper(COMPRESSED[comp](path, "rb"),
                                                    errors="replace"))
        # BLF and MF4 readers seek: the log decompressed into an unnamed temporary file
        return classes[suffix](_decompress_into(path, comp, tempfile.TemporaryFile(),
                                                str(path), "file"))
    buf = stdin_buffer()
    if suffix in (".asc", ".trc"):
        return classes[suffix](io.TextIOWrapper(buf, errors="replace"))
    return classes[suffix](buf)


def _reason(exc: BaseException) -> str:
    """A reader's error in words for the user: a text reader given binary data says so;
    another library's error is its message (its class only when it has none)."""
    if isinstance(exc, UnicodeDecodeError):
        return f"not a text file (byte 0x{exc.object[exc.start]:02x} is not UTF-8)"
    text = " ".join(str(exc).split())
    if len(text) > 120:
        text = text[:117] + "..."
    return text or type(exc).__name__


class _Skipped(logging.Handler):
    """python-can's and asammdf's log records while a file is read: a skipped record
    (warning) becomes an issue, nothing reaches stderr."""

    def __init__(self, issues: Any, frames_read: Any) -> None:
        super().__init__(logging.WARNING)
        self.issues, self.frames_read = issues, frames_read

    def emit(self, record: logging.LogRecord) -> None:
        if self.issues is not None and record.levelno < logging.ERROR:
            n = self.frames_read()
            self.issues.append(LogIssue(n + 1, f"python-can skipped a record after frame "
                                               f"{n}", record.getMessage()))


@contextmanager
def _quiet(issues: Any, frames_read: Any) -> Iterator[list[str]]:
    """Reading through python-can: its loggers' records to `issues` (not stderr), and
    the clean-up errors of a reader that failed half-built (asammdf's ``__del__``) not
    printed; yields the list the caller puts the failure's reason in."""
    handler = _Skipped(issues, frames_read)
    loggers = [logging.getLogger(n) for n in ("can", "asammdf")]
    saved = [(lg.handlers, lg.propagate) for lg in loggers]
    for lg in loggers:
        lg.handlers, lg.propagate = [handler], False
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: None
    failed: list[str] = []
    try:
        yield failed
    finally:
        if failed:
            gc.collect()        # the failed reader's objects, while their errors are muted
        sys.unraisablehook = hook
        for lg, (handlers, propagate) in zip(loggers, saved, strict=True):
            lg.handlers, lg.propagate = handlers, propagate
