"""A rig's table read as columns of numbers, for `bench import` (`bench.gap.importer`):
CSV-like text (the delimiter sniffed; also .xz/.gz/.bz2-compressed) or Parquet.

Text is read as a stream of lines (never the whole file at once): each column the map
reads grows as an array of float64, so a table costs 8 bytes per cell read plus its
line numbers, whatever its width or size; a table with more rows than the memory
available takes (`bench.trace.max_rows`) is refused as soon as it has them, and a long
read shows a bar. Parquet is read column by column, only the columns asked for.

One rule per case, each message naming the file, the column and the line (Parquet: the
row):
- a UTF-8 byte-order mark before the header is dropped (it is no part of the first
  column's name);
- a column name the header has twice, when the map reads it, is refused (which of the
  two columns is meant is unknown);
- a cell that is not a number is refused; a blank cell is NaN (no value); an infinite
  value is refused (no measurement);
- a Parquet timestamp or duration column is read as seconds (since the Unix epoch, UTC;
  its own unit and zone taken from the Parquet type), and only as the time signal:
  `Rows.timestamps` names such columns for the importer's checks;
- a text file that is not UTF-8, a corrupt compressed file, a directory: one line.
"""

from __future__ import annotations

import bz2
import codecs
import csv
import gzip
import lzma
import math
import os
import zlib
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.trace import arrow_floats, max_rows, unique_names

COMPRESSED: dict[str, Any] = {".xz": lzma.open, ".gz": gzip.open, ".bz2": bz2.open}
FINITE = "a value must be a finite number (leave a cell blank where there is no value)"
MAX_LINE_BYTES = 1 << 20
"""A table's text line longer than this is refused (no rig writes such rows; a binary
file read as text would otherwise be one line of its whole size)."""
BAR_BYTES = 16 << 20
"""Tables at least this large show a progress bar while they are read."""


@dataclass(frozen=True)
class Rows:
    """Where a table's data rows are in its file, for messages: a text table's line
    numbers (``word`` "line"), a Parquet table's row numbers from 1 ("row");
    `timestamps`: the columns read from a timestamp or duration type, in seconds."""
    path: Path
    numbers: np.ndarray
    word: str = "line"
    timestamps: frozenset[str] = field(default_factory=frozenset)

    def at(self, i: int) -> str:
        """``PATH line N`` of data row `i`."""
        return f"{self.path} {self.word} {int(self.numbers[i])}"

    def some(self, idx: np.ndarray, most: int = 5) -> str:
        """``line 7`` or ``lines 7, 9, 12 and 4 more`` of the data rows `idx`."""
        nums = [str(int(self.numbers[i])) for i in idx[:most]]
        more = f" and {len(idx) - most} more" if len(idx) > most else ""
        return f"{self.word}{'s' if len(idx) > 1 else ''} {', '.join(nums)}{more}"

    def take(self, mask: np.ndarray) -> Rows:
        return Rows(self.path, self.numbers[mask], self.word, self.timestamps)


def read_rows(path: str | Path, columns: list[str]) -> tuple[dict[str, np.ndarray], Rows]:
    """The named columns of a CSV or Parquet table as float arrays (blank -> NaN), and
    where its rows are in the file (`Rows`); the rules of the module docstring."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such table: {path}")
    suffix = path.suffix.lower()
    if suffix in COMPRESSED:
        suffix = Path(path.stem).suffix.lower()
    if suffix == ".parquet":
        return _read_parquet(path, columns)
    if suffix in (".csv", ".txt", ".tsv"):
        return _read_delimited(path, columns)
    raise BenchError(f"{path}: unknown table format {suffix!r} (use .csv or .parquet)")


def _read_parquet(path: Path, columns: list[str]) -> tuple[dict[str, np.ndarray], Rows]:
    """`read_rows` of a Parquet file (only the columns asked for are read)."""
    import pyarrow.parquet as pq
    try:
        pf = pq.ParquetFile(path)
        have = pf.schema_arrow.names
    except Exception as exc:  # noqa: BLE001 - pyarrow raises many types
        raise BenchError(f"{path}: cannot read Parquet ({exc})") from None
    _check_columns(path, columns, have, "column")
    try:
        table = pf.read(columns=sorted(set(columns)))
    except Exception as exc:  # noqa: BLE001 - pyarrow raises many types
        raise BenchError(f"{path}: cannot read Parquet ({exc})") from None
    rows = Rows(path, np.arange(table.num_rows) + 1, "row")
    out, stamps = {}, set()
    for c in columns:
        try:
            out[c], stamp = arrow_floats(table.column(c))
        except (ValueError, TypeError) as exc:
            raise BenchError(f"{path}: column {c!r} is not numeric ({exc})") from None
        if stamp:
            stamps.add(c)
        inf = np.flatnonzero(np.isinf(out[c]))
        if len(inf):
            raise BenchError(f"{rows.at(int(inf[0]))}: column {c!r} holds an infinite "
                             f"value ({out[c][inf[0]]}); {FINITE}")
    return out, Rows(path, rows.numbers, "row", frozenset(stamps))


def _read_delimited(path: Path, columns: list[str]) -> tuple[dict[str, np.ndarray], Rows]:
    """`read_rows` of a CSV-like text file (the delimiter sniffed: , ; tab or space),
    streamed line by line into one float array per column."""
    with _TextLines(path, "table") as lines:
        head = lines.head(4096)
        try:
            dialect: type[csv.Dialect] = csv.Sniffer().sniff(head, delimiters=",;\t ")
        except csv.Error:
            dialect = csv.excel
        rd = csv.reader(lines, dialect)
        try:
            header = [h.strip() for h in next(rd)]
        except StopIteration:
            raise BenchError(f"{path}: empty table") from None
        except csv.Error as exc:
            raise BenchError(f"{path} line 1: not a readable CSV header ({exc})") from None
        _check_columns(path, columns, header, "line 1: column")
        idx = [header.index(c) for c in columns]
        flat = array("d")                 # the rows' wanted cells, row after row
        numbers = array("q")
        limit = max_rows(len(columns) + 1)
        try:
            for row in rd:
                if not row or all(not x.strip() for x in row):
                    continue
                flat.extend(_row_values(path, rd.line_num, row, idx, columns))
                numbers.append(rd.line_num)
                if len(numbers) > limit:
                    raise BenchError(
                        f"{path}: more than {limit} rows of the {len(columns)} columns the "
                        f"map reads (line {rd.line_num}): more than this machine's memory "
                        "takes; split the table into parts and import each")
        except csv.Error as exc:
            raise BenchError(f"{path} line {rd.line_num}: not a readable CSV row "
                             f"({exc})") from None
    if not numbers:
        raise BenchError(f"{path}: the table has a header but no rows")
    table = np.frombuffer(flat, dtype=float).reshape(-1, len(columns))
    out = {c: table[:, j] for j, c in enumerate(columns)}      # views, no copy
    return out, Rows(path, np.frombuffer(numbers, dtype=np.int64))


class _TextLines:
    """The lines of a text file (a table decompressed when it ends in .xz, .gz or .bz2)
    as read, decoded as UTF-8 (a byte-order mark at its start dropped); a directory, an
    unreadable, corrupt or non-UTF-8 file, a line over MAX_LINE_BYTES is a one-line
    BenchError naming the file. `head` reads ahead without losing those lines."""

    def __init__(self, path: Path, what: str) -> None:
        self.path, self.what = path, what
        self.offset = 0
        self.ahead: list[str] = []
        opener = COMPRESSED.get(path.suffix.lower()) if what == "table" else None
        self.compressed = opener is not None
        try:
            self.raw = open(path, "rb")  # noqa: SIM115 - closed in __exit__
        except IsADirectoryError:
            raise BenchError(f"{path}: is a directory, not a {what} file") from None
        except OSError as exc:
            raise BenchError(f"{path}: cannot be read ({exc.strerror or exc})") from None
        self.fh: Any = opener(self.raw, "rb") if opener is not None else self.raw
        self.size = os.fstat(self.raw.fileno()).st_size
        self.bar: Any = None

    def __enter__(self) -> _TextLines:
        if self.size >= BAR_BYTES:
            from tqdm import tqdm
            self.bar = tqdm(total=self.size, unit="B", unit_scale=True,
                            desc=f"reading {self.path.name}", leave=False)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.close()
        self.fh.close()
        self.raw.close()

    def head(self, chars: int) -> str:
        """The first lines up to about `chars` characters (kept for the iteration)."""
        it = self._read()
        n = 0
        for line in it:
            self.ahead.append(line)
            n += len(line)
            if n >= chars:
                break
        self._rest = it
        return "".join(self.ahead)

    def __iter__(self) -> Iterator[str]:
        yield from self.ahead
        self.ahead = []
        yield from getattr(self, "_rest", None) or self._read()

    def _read(self) -> Iterator[str]:
        n = 0
        while True:
            raw = self._readline()
            if not raw:
                return
            if self.offset == 0 and raw.startswith(codecs.BOM_UTF8):
                raw, self.offset = raw[3:], 3
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise BenchError(
                    f"{self.path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                    f"{self.offset + exc.start}); a {self.what} file must be UTF-8 text"
                    + (" (or Parquet)" if self.what == "table" else "")) from None
            self.offset += len(raw)
            n += 1
            if self.bar is not None and n % 65536 == 0:
                self.bar.update(self.raw.tell() - self.bar.n)
            yield line

    def _readline(self) -> bytes:
        try:
            raw: bytes = self.fh.readline(MAX_LINE_BYTES + 1)
        except (OSError, EOFError, ValueError, lzma.LZMAError, zlib.error) as exc:
            if not self.compressed:
                raise BenchError(f"{self.path}: cannot be read ({exc})") from None
            raise BenchError(f"{self.path}: cannot decompress ({type(exc).__name__}: "
                             f"{exc}); is it a complete {self.path.suffix} file?") from None
        if len(raw) > MAX_LINE_BYTES:
            raise BenchError(f"{self.path}: a line longer than {MAX_LINE_BYTES} bytes at "
                             f"offset {self.offset}: not a {self.what} of text rows")
        return raw


def read_text(path: Path, what: str) -> str:
    """A (small) text file's content, by the rules of `_TextLines`."""
    with _TextLines(path, what) as lines:
        return "".join(lines)


def _row_values(path: Path, lineno: int, row: list[str], idx: list[int],
                columns: list[str]) -> list[float]:
    """The floats of one text row's wanted cells (blank or missing -> NaN)."""
    vals = []
    for i, c in zip(idx, columns, strict=True):
        x = row[i].strip() if i < len(row) else ""
        try:
            v = float(x) if x else math.nan
        except ValueError:
            raise BenchError(f"{path} line {lineno}: column {c!r} is not a number: "
                             f"{x!r}") from None
        if math.isinf(v):
            raise BenchError(f"{path} line {lineno}: column {c!r} holds an infinite value "
                             f"({x!r}); {FINITE}")
        vals.append(v)
    return vals


def _check_columns(path: Path, wanted: list[str], have: list[str], where: str) -> None:
    """BenchError for a wanted column the table lacks, or has twice (`where`: how its
    header is named in the message, e.g. ``line 1: column``)."""
    missing = [c for c in wanted if c not in have]
    if missing:
        raise BenchError(f"{path}: no column(s) {', '.join(repr(m) for m in missing)} "
                         f"(the table has: {', '.join(_shown(h) for h in have)})")
    unique_names(path, have, where, only=wanted)


def _shown(name: str) -> str:
    """A column name in a message: as it is, or quoted with escapes when it holds a
    character that does not show (a stray control or format character)."""
    return name if name.isprintable() else repr(name)
