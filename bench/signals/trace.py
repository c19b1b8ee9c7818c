"""The bench's signal table: one row per SYNC period, one column per signal.

A `Trace` is what every source produces (in-process run, live bus run, decoded candump
log, imported table) and what every consumer reads (HUMS indexes, gap diagnosis,
reports, figures). Columns are 1-D float64 numpy arrays of equal length; names carry
units. Only `t_s` is mandatory; a consumer that needs a column asks `require()` and gets
a clear error naming what is missing.

Measured columns (what crosses the bus, what a real actuator gives):
    t_s, setpoint_position_m, setpoint_speed_rad_s, mode, current_demand_a, current_a,
    motor_speed_rad_s, motor_angle_rad, position_m, load_force_n (load cell; a run
    without one simply has no such column)
Truth columns (only from a simulated plant; never used by the HUMS or the diagnosis):
    true_position_m, true_current_a, true_motor_speed_rad_s, motor_torque_nm,
    friction_torque_nm, friction_force_n, reaction_torque_nm, temperature_k,
    ext_force_n, backlash_m, friction_scale, preload_n, voltage_v
"""

from __future__ import annotations

import csv
import errno
import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.signals.tables import (  # noqa: F401 - the memory bounds are also the trace's
    MEMORY_SHARE,
    ROW_COPIES,
    TRACE_FORMATS,
    Rows,
    max_rows,
    memory_available,
    read_table,
)

TABLE_FORMATS = TRACE_FORMATS

MEASURED = ("t_s", "setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
            "current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m", "load_force_n")
TRUTH = ("true_position_m", "true_current_a", "true_motor_speed_rad_s", "motor_torque_nm",
         "friction_torque_nm", "friction_force_n", "reaction_torque_nm", "temperature_k",
         "ext_force_n", "backlash_m", "friction_scale", "preload_n", "voltage_v")

# ECU modes published on the bus (also a DBC value table)
MODE_IDLE, MODE_POSITION, MODE_SPEED = 0, 1, 2


@dataclass
class Trace:
    """Columns of equal length, plus free-form metadata (scenario, parameters, source)."""
    columns: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if "t_s" not in self.columns:
            raise BenchError("a trace needs a time column t_s")
        n = len(_column("t_s", self.columns["t_s"]))
        for k, v in list(self.columns.items()):
            arr = _column(k, v)
            if len(arr) != n:
                raise BenchError(f"trace column {k!r} has length {len(arr)}, expected {n}")
            self.columns[k] = arr

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise BenchError(f"the trace has no column {name!r} "
                             f"(it has: {', '.join(sorted(self.columns))})") from None

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(self.columns["t_s"])

    @property
    def t(self) -> np.ndarray:
        return self.columns["t_s"]

    @property
    def dt(self) -> float:
        """Median sample period (s)."""
        return float(np.median(np.diff(self.t))) if len(self) > 1 else float("nan")

    def require(self, names: Iterable[str], purpose: str) -> None:
        """Raise a BenchError naming every column `purpose` needs and the trace lacks."""
        missing = [n for n in names if n not in self.columns
                   or not np.isfinite(self.columns[n]).any()]
        if missing:
            raise BenchError(f"{purpose} needs the signal(s) {', '.join(missing)}, "
                             f"which this log/trace does not have")

    def window(self, t0: float, t1: float) -> Trace:
        m = (self.t >= t0) & (self.t < t1)
        return Trace({k: v[m] for k, v in self.columns.items()}, dict(self.meta))

    def measured(self) -> Trace:
        """Only the columns a real actuator's bus carries (drop simulation truth)."""
        return Trace({k: v for k, v in self.columns.items() if k not in TRUTH}, dict(self.meta))

    # -- files -----------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write CSV (``.csv``), Parquet (``.parquet``) or compressed numpy (``.npz``)."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".npz":
            arrays: dict[str, Any] = {"__meta__": json.dumps(self.meta, default=str),
                                      **self.columns}
            np.savez_compressed(path, **arrays)
        elif suffix == ".csv":
            with path.open("w", newline="") as fh:
                self.write_csv(fh)
        elif suffix == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq
            table = pa.table(self.columns)
            table = table.replace_schema_metadata(
                {"bench_meta": json.dumps(self.meta, default=str)})
            pq.write_table(table, path)
        else:
            raise BenchError(f"unknown table format {suffix!r} (use .csv, .parquet or .npz)")
        return path

    def write_csv(self, fh: Any) -> None:
        """The table as CSV text into the open text file `fh` (a header of the column
        names, then one row per sample, each number as its exact shortest text)."""
        names = list(self.columns)
        w = csv.writer(fh)
        w.writerow(names)
        data = np.column_stack([self.columns[n] for n in names])
        for row in data:
            w.writerow([repr(float(x)) for x in row])

    @classmethod
    def load(cls, path: str | Path) -> Trace:
        """A trace file written by `save`. A file that is not one, a time t_s that is not
        finite and strictly increasing, or an infinite value (NaN, a missing value, is
        fine) is a one-line BenchError naming the file."""
        path = Path(path)
        if not path.exists():
            raise BenchError(f"no such file: {path}")
        try:
            tab = read_table(path, formats=TRACE_FORMATS)
        except BenchError as exc:
            raise BenchError(f"{exc}; {NOT_A_TRACE}") from None
        cols, meta = tab.columns, tab.meta
        stamped = sorted(tab.rows.timestamps - {"t_s"})
        if stamped:
            raise BenchError(f"{path}: column {stamped[0]!r} holds timestamps (a Parquet "
                             "timestamp type); only the time t_s may (read as seconds)")
        if not isinstance(meta, dict):
            raise BenchError(f"{path}: its metadata is not a JSON object but "
                             f"{type(meta).__name__}; {NOT_A_TRACE}")
        if "t_s" not in cols:
            raise BenchError(f"{path}: no time column t_s (it has: "
                             f"{', '.join(sorted(cols)) or 'none'}); {NOT_A_TRACE}")
        try:
            tr = cls(cols, meta)
        except BenchError as exc:
            raise BenchError(f"{path}: {exc}") from None
        _check_loaded(path, tr, tab.rows)
        return tr


def _column(name: str, values: Any) -> np.ndarray:
    """One trace column as a 1-D float array; BenchError naming it when it is not one
    (a single value, a table, text, complex numbers)."""
    if np.iscomplexobj(values):
        raise BenchError(f"trace column {name!r} holds complex numbers, not real ones")
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise BenchError(f"trace column {name!r} is not a column of numbers ({exc})") from None
    if arr.ndim != 1:
        raise BenchError(f"trace column {name!r} is {arr.ndim}-D (shape {arr.shape}), not "
                         "one value per row")
    return arr


NOT_A_TRACE = ("not a trace the bench wrote? A rig's own table is read with "
               "`bench import TABLE --map MAP` (docs/real-data.md)")


MAX_VALUE = 1e100
"""No measured signal in SI units, nor a health index, comes near this; a squared or
summed one beyond it overflows a float. Every reader of measured values refuses a larger
one (traces here, imports, trends files)."""


def _check_loaded(path: Path, tr: Trace, rows: Rows) -> None:
    """BenchError naming `path` unless it has rows, t_s is finite and strictly increasing
    and no column holds an infinite value."""
    def row(i: int) -> str:
        return f"{rows.word} {int(rows.numbers[i])}" if i < len(rows.numbers) else f"row {i + 1}"
    t = tr.t
    if not len(t):
        raise BenchError(f"{path}: the trace has no rows (no sample to read)")
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise BenchError(f"{path} {row(int(bad[0]))}: the time t_s is {t[bad[0]]} "
                         f"({len(bad)} row(s) without a finite time); a trace needs one in "
                         "every row")
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        k = int(back[0]) + 1
        raise BenchError(f"{path} {row(k)}: the time t_s does not increase ({t[k - 1]:g} s, "
                         f"then {t[k]:g} s); a trace's time must increase from row to row")
    for name, v in tr.columns.items():
        inf = np.flatnonzero(np.isinf(v))
        if len(inf):
            raise BenchError(f"{path} {row(int(inf[0]))}: column {name!r} holds an infinite "
                             "value (a missing value is NaN; inf is no measurement)")
        huge = np.flatnonzero(np.abs(np.asarray(v, float)) > MAX_VALUE) if v.dtype.kind in "fiu" \
            else np.zeros(0, int)
        if len(huge):
            raise BenchError(f"{path} {row(int(huge[0]))}: column {name!r} holds "
                             f"{v[huge[0]]:g}, beyond any measurement (|value| > "
                             f"{MAX_VALUE:g} in SI units); its products would overflow")


def probe_output(path: str | Path, what: str) -> Path:
    """Check, before a run starts, that `path` can be written: not a directory, its
    folder exists, one byte can be written and flushed (``/dev/full`` fails here). The
    file is left as it was: a new one is removed, an existing one cut back to its size.
    BenchError ``cannot write the {what} {path}: {reason}`` otherwise."""
    p = Path(path)
    try:
        if p.is_dir():
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR))
        existed = p.exists()
        with open(p, "ab", buffering=0) as fh:
            size = fh.tell()
            fh.write(b"\n")
            if p.is_file():
                fh.truncate(size)
        if not existed and p.is_file():
            p.unlink()
    except OSError as exc:
        raise BenchError(f"cannot write the {what} {p}: {exc.strerror or exc}") from None
    return p


def check_save_path(path: str | Path) -> Path:
    """A table path for `Trace.save`: known format and writable (checked before a run)."""
    suffix = Path(path).suffix.lower()
    if suffix not in TABLE_FORMATS:
        raise BenchError(f"--save: unknown table format {suffix!r} (use .csv, .parquet or .npz)")
    return probe_output(path, "trace")


def is_number(x: str) -> bool:
    """Whether `x` parses as a float."""
    try:
        float(x)
    except ValueError:
        return False
    return True


def concat(traces: list[Trace]) -> Trace:
    names = set(traces[0].columns)
    for tr in traces[1:]:
        names &= set(tr.columns)
    return Trace({n: np.concatenate([tr.columns[n] for tr in traces]) for n in sorted(names)},
                 dict(traces[0].meta))


def from_rows(rows: list[Mapping[str, float]], meta: dict[str, Any] | None = None) -> Trace:
    names = list(rows[0]) if rows else ["t_s"]
    return Trace({n: np.array([r.get(n, np.nan) for r in rows], dtype=float) for n in names},
                 meta or {})
