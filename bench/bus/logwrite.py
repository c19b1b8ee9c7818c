"""Bus logs written through python-can: `can.Logger` picks the writer from the file's
suffix (candump ``.log``, the default; Vector ``.asc`` and ``.blf``; PEAK ``.trc``; ASAM
``.mf4``), `can.SizedRotatingLogger` starts a new file when one reaches a size (``.log``,
``.asc``, ``.blf``: the formats python-can rotates). `LOG_FORMATS` are the formats the
bench writes and reads back (`bench.bus.logread.read_frames`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import can
from can.util import channel2int

from bench import BenchError, allow_mf4_import
from bench.signals.tables import table_suffix
from bench.signals.textlines import COMPRESSED

LOG_FORMATS = {".log": "candump -L", ".asc": "Vector ASC", ".blf": "Vector BLF",
               ".trc": "PEAK TRC", ".mf4": "ASAM MDF4"}
"""Suffix -> format, for the messages; ``.log`` is candump -L (`bench.bus.logread`)."""
ROTATING_FORMATS = (".log", ".asc", ".blf")
"""The formats `can.SizedRotatingLogger` writes (of LOG_FORMATS)."""


COMPRESSIONS = tuple(COMPRESSED)
"""Compression suffixes a log to read may end in (``run.log.gz``, ``run.blf.xz``):
decompressed as it is read (`bench.bus.logread`), as the tables' readers do."""


def log_suffixes(path: str | Path) -> tuple[str, str]:
    """(the format suffix, the compression suffix or "") of a log's name, lower case:
    ``run.asc.gz`` -> (".asc", ".gz"), ``run.log`` -> (".log", "")."""
    suffix = Path(path).suffix.lower()
    return table_suffix(path), suffix if suffix in COMPRESSED else ""


def log_format(path: str | Path, what: str = "log", compressed: bool = False) -> str:
    """The format suffix of a log file (lower case) if the bench reads and writes it;
    BenchError naming the formats otherwise. `compressed`: a log to read, which may also
    end in a compression suffix (`COMPRESSIONS`; the format is the suffix before it)."""
    p = Path(path)
    suffix, comp = log_suffixes(p) if compressed else (p.suffix.lower(), "")
    if suffix not in LOG_FORMATS:
        known = ", ".join(f"{s} ({d})" for s, d in LOG_FORMATS.items())
        also = f"; also {'/'.join(COMPRESSIONS)}-compressed" if compressed else ""
        name = (suffix + comp) if comp else suffix
        raise BenchError(f"{what} {p}: unknown log format {name or '(no suffix)'!r} "
                         f"(use {known}{also})")
    return suffix


def open_writer(path: str | Path, max_bytes: int = 0) -> Any:
    """A python-can writer for `path` (its format from the suffix, `log_format`): a
    `can.SizedRotatingLogger` when `max_bytes` > 0 (a new file each time the current one
    reaches `max_bytes`; the full ones renamed ``NAME_<date>T<time>_#NNN.ext``), else the
    format's own writer through `can.Logger`. OSError when the file cannot be opened."""
    suffix = log_format(path)
    if suffix == ".mf4":
        allow_mf4_import()
    if max_bytes > 0:
        if suffix not in ROTATING_FORMATS:
            raise BenchError(f"--max-bytes: python-can rotates {', '.join(ROTATING_FORMATS)} "
                             f"logs, not {suffix}")
        return ChannelSafe(can.SizedRotatingLogger(str(path), max_bytes=max_bytes))
    return ChannelSafe(can.Logger(str(path)))


MAX_CHANNEL = 255
"""The largest channel number every format stores (ASAM MDF4 keeps it in a byte)."""


STEP_S = 1e-6
"""What a frame stamped before the line ahead of it is written at, after that line: the
candump log's resolution, so that it never shares that line's stamp (a decoder takes the
same frame with the same stamp for one frame logged twice)."""


class ChannelSafe(can.Listener):
    """A writer that stores a frame whose bus channel number it cannot hold with no
    channel. python-can's binary writers take the number from the channel name's trailing
    digits (`can.util.channel2int`): a virtual bus named ``bench-624`` made the MF4 writer
    raise OverflowError (a byte) and lose the log. The bench reads no channel back.

    Its time stamps never go backwards, as a real candump log's (stamped at reception):
    a frame stamped before the last one written is written STEP_S after it (a wall clock
    stepped back; the ECU stamps what it logs as it logs it, `EcuLink._record`)."""

    def __init__(self, inner: Any) -> None:
        object.__setattr__(self, "inner", inner)
        object.__setattr__(self, "last_ts", -math.inf)

    def on_message_received(self, msg: can.Message) -> None:
        ch = channel2int(msg.channel)
        ts = msg.timestamp
        if ts < self.last_ts:
            ts = self.last_ts + STEP_S
        if ts != msg.timestamp or (ch is not None and not 0 <= ch <= MAX_CHANNEL):
            keep = ch is None or 0 <= ch <= MAX_CHANNEL
            msg = can.Message(timestamp=ts, arbitration_id=msg.arbitration_id,
                              channel=msg.channel if keep else None,
                              is_extended_id=msg.is_extended_id, is_remote_frame=
                              msg.is_remote_frame, is_error_frame=msg.is_error_frame,
                              dlc=msg.dlc, data=msg.data, is_fd=msg.is_fd, is_rx=msg.is_rx,
                              bitrate_switch=msg.bitrate_switch,
                              error_state_indicator=msg.error_state_indicator)
        self.inner.on_message_received(msg)
        object.__setattr__(self, "last_ts", ts)

    def stop(self) -> None:
        self.inner.stop()

    def __getattr__(self, name: str) -> Any:       # file, writer, file_size, ...
        return getattr(self.inner, name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self.inner, name, value)


def flush(writer: Any) -> None:
    """Push what `writer` (from `open_writer`) has written so far to the file, where its
    format writes as it goes (text formats; BLF keeps its open container, MF4 writes on
    `stop`)."""
    inner = getattr(writer, "writer", writer)      # a rotating logger's current file
    fh = getattr(inner, "file", None)
    if fh is not None and not getattr(fh, "closed", False):
        fh.flush()
