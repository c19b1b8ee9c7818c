"""The one reader of tables: a rig's own table (`bench import`, `bench rig`) and a trace
the bench wrote (`bench.signals.trace.Trace.load`), read as columns of numbers. The reader is
chosen by the file's suffix through `TABLE_READERS` (as python-can's
``can.io.MESSAGE_READERS`` picks a log reader): CSV-like text (``.csv``, ``.tsv``,
``.txt``; the delimiter sniffed; also .xz/.gz/.bz2-compressed), Parquet and compressed
numpy (``.npz``). A caller names the formats it takes; another suffix is a one-line
BenchError naming them.

Text up to `FAST_BYTES` is parsed at once by pyarrow where that reads the same; other
text is streamed line by line, each column read growing as a float64 array (8 bytes a
cell, whatever the table's width or size), refused once it has more rows than the
memory takes (`max_rows`), with a bar. Parquet is read by column, only those asked for.

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
- every column read (no list of names): a row with more or fewer fields than the header
  is refused;
- `read_table(..., text=...)`: a column that is not all numbers is not refused but given
  as its cells' text (None for a blank cell), as a rig table's label columns are;
- a text file that is not UTF-8, a corrupt compressed file, a directory: one line.
"""

from __future__ import annotations

import codecs
import csv
import io
import math
import os
import re
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.signals.textlines import COMPRESSED, TextLines

FINITE = "a value must be a finite number (leave a cell blank where there is no value)"
FAST_BYTES = 32 << 20
"""Text tables up to this size as text are parsed at once by pyarrow (`_arrow_delimited`,
a peak of a few times this size); larger ones are streamed line by line."""
# a table or trace held in memory: 8-byte values, and up to 3 copies alive at once (the
# columns, the temporaries of the set-point functions, the table built to save it)
ROW_COPIES = 3
MEMORY_SHARE = 0.5    # of the memory available when the run starts


def arrow_floats(column: Any) -> tuple[np.ndarray, bool]:
    """A pyarrow column as float64 and whether it was a timestamp or duration (then in
    seconds: since the Unix epoch in UTC for a timestamp, whatever its own unit and
    zone). TypeError/ValueError for a column that is not numbers."""
    import pyarrow as pa
    import pyarrow.compute as pc
    kind = column.type
    if pa.types.is_timestamp(kind) or pa.types.is_duration(kind):
        unit = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[kind.unit]
        ints = pc.cast(column, pa.int64()).to_numpy(zero_copy_only=False)
        return np.asarray(ints, dtype=float) * unit, True
    if pa.types.is_date(kind):
        raise TypeError("a date column, not a time of day")
    if not (pa.types.is_integer(kind) or pa.types.is_floating(kind)
            or pa.types.is_boolean(kind) or pa.types.is_null(kind)
            or pa.types.is_decimal(kind) or pa.types.is_dictionary(kind)):
        raise TypeError(f"of type {kind}")
    return column.to_numpy(zero_copy_only=False).astype(float), False


def unique_names(path: Path | str, names: list[str], where: str,
                 only: list[str] | None = None) -> None:
    """BenchError naming a column name given twice (which one is meant is unknown); with
    `only`, just those names are checked."""
    for n in dict.fromkeys(names if only is None else only):
        at = [i + 1 for i, h in enumerate(names) if h == n]
        if len(at) > 1:
            raise BenchError(f"{path} {where} {n!r} appears {len(at)} times in the header "
                             f"(columns {', '.join(map(str, at))}): which one is meant is "
                             "unknown; rename the others")


def memory_available() -> int:
    """Bytes of memory available to a new allocation now (Linux ``MemAvailable``, else
    the free physical pages)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return 1 << 33


def max_rows(n_columns: int, available: int | None = None) -> int:
    """How many rows of `n_columns` float64 columns a trace may have: MEMORY_SHARE of the
    memory available, counting ROW_COPIES copies of every row."""
    avail = memory_available() if available is None else available
    return int(avail * MEMORY_SHARE) // (8 * n_columns * ROW_COPIES)

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


@dataclass
class Table:
    """A table as read: float64 columns, where its rows are (`Rows`), its metadata (a
    bench trace's, {} for a rig's table) and, when asked for, its text columns."""
    columns: dict[str, np.ndarray]
    rows: Rows
    meta: Any = field(default_factory=dict)
    text: dict[str, np.ndarray] = field(default_factory=dict)


Reader = Callable[[Path, "list[str] | None", bool, bool], Table]
"""(path, the columns to read or None for all, keep text columns, refuse inf) -> Table."""


@dataclass(frozen=True)
class TableFormat:
    name: str
    read: Reader


def _read_parquet(path: Path, columns: list[str] | None, text: bool, finite: bool) -> Table:
    """A Parquet file's columns (only those asked for are read), its bench metadata."""
    import json

    import pyarrow.parquet as pq
    try:
        pf = pq.ParquetFile(path)
        have = pf.schema_arrow.names
        if columns is None:
            unique_names(path, have, "column")
        else:
            _check_columns(path, columns, have, "column")
        table = pf.read(columns=None if columns is None else sorted(set(columns)))
        md = table.schema.metadata or {}
        meta = json.loads(md.get(b"bench_meta", b"{}"))
    except BenchError:
        raise
    except Exception as exc:  # noqa: BLE001 - pyarrow and json raise many types
        raise BenchError(f"{path}: cannot read Parquet ({type(exc).__name__}: {exc})"
                         ) from None
    rows = Rows(path, np.arange(table.num_rows) + 1, "row")
    out, strings, stamps = {}, {}, set()
    for c in table.column_names if columns is None else columns:
        try:
            out[c], stamp = arrow_floats(table.column(c))
        except (ValueError, TypeError) as exc:
            if not text:
                raise BenchError(f"{path}: column {c!r} is not numeric ({exc})") from None
            strings[c] = np.array([None if x is None else str(x)
                                   for x in table.column(c).to_pylist()], dtype=object)
            continue
        if stamp:
            stamps.add(c)
        inf = np.flatnonzero(np.isinf(out[c])) if finite else np.array([], dtype=int)
        if len(inf):
            raise BenchError(f"{rows.at(int(inf[0]))}: column {c!r} holds an infinite "
                             f"value ({out[c][inf[0]]}); {FINITE}")
    return Table(out, Rows(path, rows.numbers, "row", frozenset(stamps)), meta, strings)


def _read_npz(path: Path, columns: list[str] | None, text: bool, finite: bool) -> Table:
    """A compressed numpy file's arrays (a bench trace: its metadata in ``__meta__``)."""
    import json
    import zipfile
    if not zipfile.is_zipfile(path):           # np.load would try it as a pickle
        raise BenchError(f"{path}: not a readable .npz table (not a zip archive, as an "
                         ".npz file is)")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["__meta__"])) if "__meta__" in z else {}
            cols = {k: z[k] for k in z.files if k != "__meta__"}
    except Exception as exc:  # noqa: BLE001 - zipfile, numpy and json raise many types
        raise BenchError(f"{path}: not a readable .npz table ({type(exc).__name__}: "
                         f"{exc})") from None
    if columns is not None:
        _check_columns(path, columns, list(cols), "array")
        cols = {c: cols[c] for c in columns}
    n = max((len(np.atleast_1d(v)) for v in cols.values()), default=0)
    return Table(cols, Rows(path, np.arange(n) + 1, "row"), meta)


def _read_delimited(path: Path, columns: list[str] | None, text: bool,
                    finite: bool) -> Table:
    """A CSV-like text file (the delimiter sniffed: , ; tab or space), streamed line by
    line into one float array per column read (with `text`: the cells, then a column
    of numbers or of text each)."""
    with TextLines(path, "table") as lines:
        dialect = sniff_dialect(lines.head(4096))
        if (fast := _arrow_delimited(path, dialect.delimiter, columns, text, finite)):
            return fast
        rd = csv.reader(lines, dialect)
        try:
            header = [h.strip() for h in next(rd)]
        except StopIteration:
            raise BenchError(f"{path}: empty table") from None
        except csv.Error as exc:
            raise BenchError(f"{path} line 1: not a readable CSV header ({exc})") from None
        every = columns is None
        if columns is None:
            unique_names(path, header, "line 1: column")
            columns = header
        else:
            _check_columns(path, columns, header, "line 1: column")
        idx = [header.index(c) for c in columns]
        sink: _Floats | _Cells = _Cells(idx) if text else _Floats(path, idx, columns, finite)
        numbers = array("q")
        limit = max_rows(len(columns) + 1)
        try:
            for row in rd:
                if not row or (not every and all(not x.strip() for x in row)):
                    continue
                if every and len(row) != len(header):
                    raise BenchError(f"{path} line {rd.line_num}: {len(row)} fields, the "
                                     f"header has {len(header)}")
                sink.add(rd.line_num, row, idx)
                numbers.append(rd.line_num)
                if len(numbers) > limit:
                    raise BenchError(
                        f"{path}: more than {limit} rows of the {len(columns)} columns "
                        f"read (line {rd.line_num}): more than this machine's memory "
                        "takes; split the table into parts and import each")
        except csv.Error as exc:
            raise BenchError(f"{path} line {rd.line_num}: not a readable CSV row "
                             f"({exc})") from None
    if not numbers:
        raise BenchError(f"{path}: the table has a header but no rows")
    out, strings = sink.columns(columns)
    return Table(out, Rows(path, np.frombuffer(numbers, dtype=np.int64)), {}, strings)


def sniff_dialect(head: str, delimiters: str = ",;\t ") -> type[csv.Dialect]:
    """The CSV dialect of a text table's first lines (`head`): its delimiter one of
    `delimiters` (Python's csv.Sniffer), the comma where none shows."""
    try:
        return csv.Sniffer().sniff(head, delimiters=delimiters)
    except csv.Error:
        return csv.excel


def _arrow_delimited(path: Path, delimiter: str, columns: list[str] | None, text: bool,
                     finite: bool) -> Table | None:
    """The table as the line reader reads it, parsed at once by pyarrow (4-8x faster on a
    rig's table), or None where the two could differ (a quote, a carriage return, a
    blank line among named columns, a header name spaced, empty or twice, a ragged row,
    an inf with `finite`, text without `text`, no or too many rows): the line reader
    then reads it and names what is wrong. Text cells follow its rule (`_text_column`)."""
    opener = COMPRESSED.get(path.suffix.lower())
    if delimiter not in ",;\t" or path.stat().st_size > FAST_BYTES:
        return None
    try:
        with (opener or open)(path, "rb") as fh:
            data = b"".join(islice(iter(lambda: fh.read(1 << 20), b""), FAST_BYTES >> 20 | 1))
        data.decode("utf-8")
    except Exception:  # noqa: BLE001 - the line reader names what is wrong
        return None
    data = data.removeprefix(codecs.BOM_UTF8)
    d = re.escape(delimiter.encode())
    if (len(data) > FAST_BYTES or b'"' in data or b"\r" in data
            or (columns is not None
                and re.search(rb"(?m)^(?:[ \t]|" + d + rb")+$", data))):
        return None
    header = data[:data.find(b"\n") if b"\n" in data else len(data)].decode().split(delimiter)
    if (any(not h or h != h.strip() for h in header) or len(set(header)) != len(header)
            or (columns is not None and not set(columns) <= set(header))):
        return None
    ends = np.flatnonzero(np.frombuffer(data, np.uint8) == 10)
    lengths = np.append(ends, len(data)) - np.concatenate(([0], ends + 1))
    numbers = (np.flatnonzero(lengths > 0) + 1)[1:]        # the data rows' line numbers
    wanted = header if columns is None else columns
    if not len(numbers) or len(numbers) > max_rows(len(wanted) + 1):
        return None
    import pyarrow as pa
    import pyarrow.csv as pacsv

    def read(convert: Any) -> Any:
        return pacsv.read_csv(io.BytesIO(data), pacsv.ReadOptions(use_threads=False),
                              pacsv.ParseOptions(delimiter=delimiter), convert)
    try:
        tab = read(pacsv.ConvertOptions(include_columns=wanted, null_values=[""],
                                        strings_can_be_null=True))
    except (pa.ArrowInvalid, ValueError):
        return None                                  # a ragged row, for one
    cols = _arrow_columns(tab, wanted, text, finite, read)
    return None if cols is None else Table(cols[0], Rows(path, numbers), {}, cols[1])


def _arrow_columns(tab: Any, wanted: list[str], text: bool, finite: bool,
                   read: Callable[[Any], Any]) -> tuple[dict[str, np.ndarray],
                                                        dict[str, np.ndarray]] | None:
    """`_arrow_delimited`'s numbers and text (None: the line reader must read it)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    out: dict[str, np.ndarray] = {}
    strings: dict[str, np.ndarray] = {}
    for c in wanted:
        col = tab.column(c)
        if pa.types.is_integer(col.type) or pa.types.is_floating(col.type) \
                or pa.types.is_null(col.type):
            out[c] = col.to_numpy(zero_copy_only=False).astype(float)
            if finite and np.isinf(out[c]).any():
                return None
            continue
        if not text:
            return None
        if not pa.types.is_string(col.type):         # a date, a bool: its cells as written
            col = read(pacsv.ConvertOptions(include_columns=[c], null_values=[""],
                                            column_types={c: pa.string()},
                                            strings_can_be_null=True)).column(c)
        numbers_or_text = _text_column([x or "" for x in col.to_pylist()])
        (out if numbers_or_text.dtype != object else strings)[c] = numbers_or_text
    return out, strings


class _Floats:
    """The wanted cells of each row as floats (a cell that is not a number refused)."""

    def __init__(self, path: Path, idx: list[int], names: list[str], finite: bool) -> None:
        self.path, self.idx, self.names, self.finite = path, idx, names, finite
        self.flat = array("d")             # the rows' wanted cells, row after row

    def add(self, lineno: int, row: list[str], idx: list[int]) -> None:
        self.flat.extend(_row_values(self.path, lineno, row, idx, self.names, self.finite))

    def columns(self, names: list[str]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        table = np.frombuffer(self.flat, dtype=float).reshape(-1, len(names))
        return {c: table[:, j] for j, c in enumerate(names)}, {}     # views, no copy


class _Cells:
    """The rows as text; at the end each wanted column is one of numbers where every cell
    is one (blank: NaN), else of its cells' text (blank: None)."""

    def __init__(self, idx: list[int]) -> None:
        self.idx = idx
        self.rows: list[list[str]] = []

    def add(self, lineno: int, row: list[str], idx: list[int]) -> None:
        self.rows.append(row)

    def columns(self, names: list[str]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        width = max(self.idx, default=-1) + 1
        rows = [r if len(r) >= width else r + [""] * (width - len(r)) for r in self.rows]
        by_column = list(zip(*rows, strict=False)) if rows else [() for _ in range(width)]
        out: dict[str, np.ndarray] = {}
        strings: dict[str, np.ndarray] = {}
        for i, c in zip(self.idx, names, strict=True):
            col = _text_column(by_column[i])
            (out if col.dtype != object else strings)[c] = col
        return out, strings


def _text_column(cells: Any) -> np.ndarray:
    """A column of text cells as numbers where every cell is one (blank: NaN), else as its
    cells' text (blank: None, dtype object)."""
    try:
        return np.fromiter(map(float, cells), float, len(cells))      # all numbers
    except ValueError:
        try:
            return np.array([float(x) if x.strip() else math.nan for x in cells])
        except ValueError:
            return np.array([x if x.strip() else None for x in cells], dtype=object)


TABLE_READERS: dict[str, TableFormat] = {
    ".csv": TableFormat("CSV", _read_delimited),
    ".tsv": TableFormat("tab-separated text", _read_delimited),
    ".txt": TableFormat("delimited text", _read_delimited),
    ".parquet": TableFormat("Parquet", _read_parquet),
    ".npz": TableFormat("compressed numpy", _read_npz),
}
"""Table suffix -> its reader (a text table may also end in .xz, .gz or .bz2)."""
IMPORT_FORMATS = (".csv", ".tsv", ".txt", ".parquet")
"""What `bench import` reads: a rig's own table."""
TRACE_FORMATS = (".csv", ".parquet", ".npz")
"""What `bench.signals.trace.Trace.save` writes and `Trace.load` reads."""


def table_suffix(path: str | Path) -> str:
    """A table's format suffix, lower case, under a compression suffix:
    ``spalling1.csv.xz`` -> ``.csv``."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in COMPRESSED:
        suffix = Path(p.stem).suffix.lower()
    return suffix


def file_suffixes(formats: tuple[str, ...]) -> tuple[str, ...]:
    """The file name endings of `formats`, with the compressed text ones:
    ``.csv``, ``.csv.xz``, ``.csv.gz``, ``.csv.bz2``, ``.parquet`` ..."""
    out: list[str] = []
    for s in formats:
        out.append(s)
        if TABLE_READERS[s].read is _read_delimited:
            out += [s + c for c in COMPRESSED]
    return tuple(out)


def reader_for(path: str | Path, formats: tuple[str, ...] | None = None) -> TableFormat:
    """The reader of `path` by its suffix (`TABLE_READERS`, of `formats` when given); a
    one-line BenchError naming the known ones for another suffix."""
    known = tuple(TABLE_READERS) if formats is None else formats
    suffix = table_suffix(path)
    if suffix not in known:
        raise BenchError(f"{path}: unknown table format {suffix or '(no suffix)'!r} (use "
                         f"{', '.join(known)}; text also .xz/.gz/.bz2-compressed)")
    return TABLE_READERS[suffix]


def read_table(path: str | Path, columns: list[str] | None = None, *,
               formats: tuple[str, ...] | None = None, text: bool = False,
               finite: bool = False) -> Table:
    """A table read by the reader of its suffix (`reader_for`): the named `columns`
    (None: every column), by the rules of the module docstring; `text`: a column that is
    not all numbers comes in `Table.text`; `finite`: an infinite value is refused."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such table: {path}")
    reader = reader_for(path, formats)
    if path.is_dir():
        raise BenchError(f"{path}: is a directory, not a table file")
    return reader.read(path, columns, text, finite)


def read_rows(path: str | Path, columns: list[str]) -> tuple[dict[str, np.ndarray], Rows]:
    """The named columns of a rig's table (IMPORT_FORMATS) as float arrays (blank ->
    NaN, infinite refused), and where its rows are in the file (`Rows`)."""
    t = read_table(path, columns, formats=IMPORT_FORMATS, finite=True)
    return t.columns, t.rows


def _row_values(path: Path, lineno: int, row: list[str], idx: list[int],
                columns: list[str], finite: bool = True) -> list[float]:
    """The floats of one text row's wanted cells (blank or missing -> NaN)."""
    vals = []
    for i, c in zip(idx, columns, strict=True):
        x = row[i].strip() if i < len(row) else ""
        try:
            v = float(x) if x else math.nan
        except ValueError:
            raise BenchError(f"{path} line {lineno}: column {c!r} is not a number: "
                             f"{x!r}") from None
        if finite and math.isinf(v):
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
