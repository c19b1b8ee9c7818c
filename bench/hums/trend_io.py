"""Reading a trends file: one health index per test, over real time, from any rig.

`read_table(path)` reads a CSV of health-index tests into `Trend`s (one per actuator and
index), refusing what cannot be a trend with a one-line `BenchError` naming the line.
The text is read as the table reader reads it (`bench.signals.tables`: UTF-8, a
byte-order mark dropped, .xz/.gz/.bz2 decompressed, its delimiter sniffed among comma,
semicolon and tab; with one of the latter two a decimal comma, ``2,15``, is a number);
``-`` is standard input:

- **time**: a column named ``time``, ``date``, ``day`` or ``days`` (else the first whose
  name holds "date" or "time"): numbers (days, or the
  unit the file uses) or ISO 8601 dates and date-times (``2024-03-01``,
  ``2024-03-01T08:00``; time zones all given or all left out). Dates become days since
  the first test (`Trend.t`) and keep their calendar (`Trend.t0`). A time must be finite
  and within +-1e7 days (27,000 years): larger ones are not test days (and overflow the
  filter's arithmetic);
- **actuator**: optional (one actuator, named after the file, without it);
- **index and value** (long form): ``index`` (free text) and ``value`` columns, with an
  optional ``unit`` column; or the wide form: every other column is an index, its name
  the header (``rms_current [A]`` gives the unit ``A``);
- **values**: numbers; an empty cell or ``nan`` is a missing test (skipped, counted in
  `Table.notes`); ``inf`` is refused (no index is infinite; an overflow upstream), and
  so is a magnitude beyond 1e100 (its squares overflow);
- **one test per time**: a second value of an index at the same time for the same
  actuator is refused (a merge would hide it); rows out of time order are sorted, with a
  note.

Rows whose index is ``exposure`` (the Archard exposure used since the previous test, N
rev; `bench hums campaign --usage --trends-out` writes them) are usage, not a health
index: `Table.exposure`.
"""

from __future__ import annotations

import csv
import math
import re
import sys
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.signals.trace import MAX_VALUE  # |value| beyond: refused, as in a trace

TIME_NAMES = ("time", "date", "day", "days")
EXPOSURE = "exposure"
MAX_ABS_TIME = 1e7
STDIN = "-"
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")
_UNIT_IN_NAME = re.compile(r"^(.*?)\s*[\[(]([^\])]*)[\])]\s*$")


@dataclass
class Trend:
    """One index of one actuator: test times (days since the first test when the file
    gives dates, else the file's own numbers), values (NaN: a missing test), the file's
    line of each test, the unit ('' when none is given)."""
    actuator: str
    index: str
    unit: str
    t: np.ndarray
    y: np.ndarray
    lines: np.ndarray
    t0: datetime | None = None            # calendar of t = 0 when the file gives dates

    def date(self, t: float) -> str:
        """Time `t` as the file gives it: a date (ISO) or the number."""
        if self.t0 is None:
            return f"{t:g}"
        from datetime import timedelta
        d = self.t0 + timedelta(days=float(t))
        if self.t0.tzinfo is not None:
            return d.isoformat(timespec="minutes")
        whole = d.hour == d.minute == d.second == 0 and abs(t - round(t)) < 1e-9
        return d.date().isoformat() if whole else d.isoformat(timespec="minutes")


@dataclass
class Table:
    """The trends of a file, its usage rows and notes on what was read."""
    path: Path
    trends: list[Trend]
    exposure: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    dates: bool = False
    notes: list[str] = field(default_factory=list)

    def indexes(self) -> list[str]:
        return sorted({tr.index for tr in self.trends})


class _Times:
    """Parses the time column: all numbers or all ISO dates (cached per distinct text)."""

    def __init__(self, path: Path, comma: bool = False, date_format: str | None = None
                 ) -> None:
        self.path = path
        self.comma = comma
        self.date_format = date_format
        self.kind: str | None = None       # "number" or "date"
        self.aware: bool | None = None
        self.cache: dict[str, float] = {}

    def __call__(self, text: str, line: int) -> float:
        got = self.cache.get(text)
        if got is not None:
            return got
        v = self._parse(text.strip(), line)
        self.cache[text] = v
        return v

    def _parse(self, s: str, line: int) -> float:
        where = f"{self.path}:{line}"
        try:
            if self.date_format:
                raise ValueError(s)             # a stated format: the times are dates
            v, kind = _number(s, self.comma), "number"
        except ValueError:
            v, kind = self._date(s, where), "date"
        if self.kind is not None and kind != self.kind:
            raise BenchError(f"{where}: time {s!r} mixes numbers and dates in one column")
        self.kind = kind
        if not math.isfinite(v) or abs(v) > (MAX_ABS_TIME if kind == "number" else 1e9):
            raise BenchError(f"{where}: time {s!r} is out of range (finite, within "
                             f"+-{MAX_ABS_TIME:g} days)")
        return v

    def _date(self, s: str, where: str) -> float:
        """An ISO date or date-time in days since 1970 (naive ones read as UTC)."""
        try:
            d = (datetime.strptime(s, self.date_format) if self.date_format
                 else datetime.fromisoformat(s))
        except ValueError:
            d = None
        if d is None and self.date_format:
            raise BenchError(f"{where}: time {s!r} is not a date of --date-format "
                             f"{self.date_format!r}")
        if d is None:
            raise BenchError(f"{where}: time {s!r} is neither a number nor an ISO date "
                             "(2024-03-01, 2024-03-01T08:00; another layout: --date-format, "
                             "e.g. '%d/%m/%Y')")
        aware = d.tzinfo is not None
        if self.aware is not None and aware != self.aware:
            raise BenchError(f"{where}: time {s!r} mixes dates with and without a time zone")
        self.aware = aware
        return (d if aware else d.replace(tzinfo=UTC)).timestamp() / 86400.0


def _number(s: str, comma: bool) -> float:
    """float(s), a decimal comma read as a point when `comma` (1,25 or -0,5e-3)."""
    if comma and _DECIMAL_COMMA.match(s):
        s = s.replace(",", ".")
    return float(s)


def _value(text: str, where: str, comma: bool = False) -> float:
    s = text.strip()
    if s == "" or s.lower() in ("nan", "na", "n/a"):
        return math.nan
    try:
        v = _number(s, comma)
    except ValueError:
        raise BenchError(f"{where}: value {s!r} is not a number") from None
    if math.isinf(v):
        raise BenchError(f"{where}: value {s!r} is infinite: not a health index")
    if abs(v) > MAX_VALUE:
        raise BenchError(f"{where}: value {s!r} is beyond +-{MAX_VALUE:g}: not a health "
                         "index (and its squares overflow the filter's arithmetic)")
    return v


def _header(path: Path, names: list[str]) -> dict[str, int]:
    """Column positions by lower-cased, stripped name (BOM removed); duplicates refused."""
    cols: dict[str, int] = {}
    for k, n in enumerate(names):
        key = n.replace("\ufeff", "").strip().lower()
        if key in cols:
            raise BenchError(f"{path}:1: column {n.strip()!r} appears twice in the header")
        cols[key] = k
    return cols


def _time_column(path: Path, cols: dict[str, int]) -> int:
    """The time column: one named as TIME_NAMES, else the first whose name holds "date"
    or "time" (``timestamp``, ``test date``)."""
    for n in TIME_NAMES:
        if n in cols:
            return cols[n]
    for n, k in sorted(cols.items(), key=lambda kv: kv[1]):
        if "date" in n or "time" in n:
            return k
    raise BenchError(f"{path}: no time column (a header named one of "
                     f"{', '.join(TIME_NAMES)}, or holding 'date' or 'time')")


def read_table(path: str | Path, progress: bool = False, date_format: str | None = None
               ) -> Table:
    """The trends of a CSV (module docstring); ``-`` reads standard input. `progress`:
    a bar in bytes on a large file (`bench.signals.textlines.TextLines`); `date_format`:
    the time column's dates by this `strptime` format (``%d/%m/%Y``) instead of ISO."""
    from bench.signals.textlines import TextLines
    if str(path) == STDIN:
        with _StdinLines() as lines:
            return _read(Path("<stdin>"), lines, "stdin", date_format)
    p = Path(path)
    if p.is_dir():
        raise BenchError(f"{p} is a directory, not a trends file (name the CSV in it)")
    if not p.is_file():
        raise BenchError(f"no trends file {p}")
    from bench.signals.textlines import COMPRESSED
    stem = Path(p.stem).stem if p.suffix.lower() in COMPRESSED else p.stem
    with TextLines(p, "trends", compressed=True, bar=progress) as lines:
        return _read(p, lines, stem, date_format)


class _StdinLines:
    """Standard input's lines, read ahead for the dialect as `TextLines` does (never
    closed here: the head's early stop must not close standard input)."""

    def __init__(self) -> None:
        self.ahead: list[str] = []

    def __enter__(self) -> _StdinLines:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def head(self, chars: int) -> str:
        n = 0
        while n < chars and (line := self._line()):
            self.ahead.append(line)
            n += len(line)
        return "".join(self.ahead)

    def __iter__(self) -> Iterator[str]:
        yield from self.ahead
        self.ahead = []
        while line := self._line():
            yield line

    @staticmethod
    def _line() -> str:
        try:
            return sys.stdin.readline()
        except UnicodeDecodeError as exc:
            raise BenchError(f"<stdin>: not UTF-8 text (byte 0x{exc.object[exc.start]:02x}"
                             "): not a trends CSV") from None


@dataclass
class _Layout:
    """Where a row's fields are: time, actuator, and the long or the wide form."""
    n: int
    time: int
    actuator: int | None
    index: int | None = None              # long form: index, value, unit columns
    value: int | None = None
    unit: int | None = None
    wide: list[tuple[int, str, str]] = field(default_factory=list)

    def cells(self, row: list[str]) -> list[tuple[str, str, str]]:
        """(index name, value text, unit) of each health index in `row`."""
        if self.index is not None and self.value is not None:
            return [(row[self.index].strip(), row[self.value],
                     row[self.unit].strip() if self.unit is not None else "")]
        return [(name, row[k], unit) for k, name, unit in self.wide]


def _layout(p: Path, names: list[str]) -> _Layout:
    cols = _header(p, names)
    it = _time_column(p, cols)
    ia = cols.get("actuator")
    if "value" in cols:
        if "index" not in cols:
            raise BenchError(f"{p}: the long form needs the columns time, actuator, index, "
                             "value; missing index")
        return _Layout(len(names), it, ia, cols["index"], cols["value"], cols.get("unit"))
    used = {it} | ({ia} if ia is not None else set())
    wide = [(k, *_split_unit(n)) for k, n in enumerate(names) if k not in used]
    if not wide:
        raise BenchError(f"{p}: no index column (time plus one column per index, or the "
                         "long form time, actuator, index, value)")
    return _Layout(len(names), it, ia, wide=wide)


def _read(p: Path, lines: Any, stem: str, date_format: str | None = None) -> Table:
    """The rows of the open text `lines` into a `Table` (the delimiter sniffed among
    comma, semicolon and tab; with another than the comma, a decimal comma is read as a
    point); `stem`: the actuator's name when the file has no actuator column."""
    from bench.signals.tables import sniff_dialect
    dialect = sniff_dialect(lines.head(4096), ",;\t")
    comma = dialect.delimiter != ","
    rows = _rows(p, csv.reader(lines, dialect))
    names = next(rows, (1, []))[1]
    if not names:
        raise BenchError(f"{p}: empty file (a header row and one row per test)")
    lay = _layout(p, names)
    times = _Times(p, comma, date_format)
    acc: dict[tuple[str, str], tuple[array, array, array]] = {}
    units: dict[tuple[str, str], tuple[str, int]] = {}
    missing = 0
    for line, row in rows:
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if len(row) != lay.n:
            raise BenchError(f"{p}:{line}: {len(row)} fields, the header has {lay.n}")
        t = times(row[lay.time], line)
        a = row[lay.actuator].strip() if lay.actuator is not None else stem
        for name, text, unit in lay.cells(row):
            v = _value(text, f"{p}:{line}", comma)
            if math.isnan(v):
                missing += 1
                continue
            key = (a, name)
            if key not in acc:
                acc[key] = (array("d"), array("d"), array("q"))
                units[key] = (unit, line)
            elif units[key][0] != unit:
                raise BenchError(f"{p}:{line}: index {name!r} of actuator {a!r} in unit "
                                 f"{unit!r} here, {units[key][0]!r} at line {units[key][1]}")
            ts, ys, ls = acc[key]
            ts.append(t)
            ys.append(v)
            ls.append(line)
    if not acc:
        raise BenchError(f"{p}: no tests (a header row and one row per test)")
    return _assemble(p, acc, units, times, missing)


def _rows(p: Path, rd: Any) -> Iterator[tuple[int, list[str]]]:
    """The rows of the csv reader `rd` with the line each ends on; a row the csv module
    cannot read (a field over its size limit, a stray quote in a strict dialect) is a
    one-line BenchError naming the file and the line, as `bench import` says it."""
    while True:
        try:
            row = next(rd)
        except StopIteration:
            return
        except csv.Error as exc:
            what = "header" if rd.line_num <= 1 else "row"
            raise BenchError(f"{p}:{rd.line_num}: not a readable CSV {what} ({exc})"
                             ) from None
        yield rd.line_num, row


def _split_unit(name: str) -> tuple[str, str]:
    m = _UNIT_IN_NAME.match(name.strip())
    return (m.group(1).strip(), m.group(2).strip()) if m else (name.strip(), "")


def _assemble(p: Path, acc: dict[tuple[str, str], tuple[array, array, array]],
              units: dict[tuple[str, str], tuple[str, int]], times: _Times,
              missing: int) -> Table:
    """Sorted, checked trends from the accumulated rows."""
    notes = []
    if missing:
        notes.append(f"{missing} missing value(s) (empty or nan) skipped")
    dates = times.kind == "date"
    t_first = min(min(ts) for ts, _, _ in acc.values()) if dates else 0.0
    t0 = datetime.fromtimestamp(t_first * 86400.0, tz=UTC) if dates else None
    if t0 is not None and not times.aware:
        t0 = t0.replace(tzinfo=None)
    trends, exposure, unsorted = [], {}, []
    for (a, name), (ts, ys, ls) in acc.items():
        t = np.frombuffer(ts, dtype=float) - t_first
        y = np.frombuffer(ys, dtype=float).copy()
        lines = np.array(ls, dtype=np.int64)
        order = np.argsort(t, kind="stable")
        if np.any(order != np.arange(len(t))):
            unsorted.append(a)
            t, y, lines = t[order], y[order], lines[order]
        dup = np.flatnonzero(np.diff(t) == 0)
        if len(dup):
            k = dup[0]
            raise BenchError(f"{p}:{lines[k + 1]}: a second value of {name!r} for actuator "
                             f"{a!r} at time {_as_given(times, t[k] + t_first)} (the first "
                             f"at line {lines[k]}): one test per time")
        if name == EXPOSURE:
            exposure[a] = (t, y)
            continue
        trends.append(Trend(a, name, units[(a, name)][0], t, y, lines, t0))
    if unsorted:
        notes.append("rows out of time order sorted (actuator "
                     + ", ".join(sorted(set(unsorted))[:3]) + ")")
    if not trends:
        raise BenchError(f"{p}: only exposure rows, no health index")
    return Table(p, trends, exposure, dates, notes)


def _as_given(times: _Times, t: float) -> str:
    if times.kind != "date":
        return f"{t:g}"
    return datetime.fromtimestamp(t * 86400.0, tz=UTC).isoformat(timespec="minutes")
