"""Import a signal table logged by another rig (`bench import TABLE --map MAP`).

Many rigs do not log CAN. A CSV or Parquet table (CSV also .xz/.gz/.bz2-compressed) at
any fixed or varying sample rate, with a column map, becomes the bench's signal table
(`bench.signals.trace.Trace`), ready for `bench gap`, `bench calibrate` and the HUMS.

The map (JSON or CSV) gives, per bench signal: the source column, its unit and an
optional scale (for angles an optional wrap period in raw values to unwrap; ``minus``: a
column subtracted from ``column`` before scaling, e.g. the position from a set-point and
a position-error column):

    JSON  [{"signal": "position_m", "column": "lvdt", "unit": "mm", "scale": 1.0}, ...]
          or {"position_m": {"column": "lvdt", "unit": "mm"}, "t_s": "time", ...}
    CSV   signal,column,unit,scale[,wrap[,minus]]

value_SI = (raw - minus) x scale x unit factor (force: N, kN, lbf, kgf = 9.80665 N). The
time signal is ``t_s``; without it, give the table's fixed rate (``source_rate_hz``).

By default the trace keeps the table's own sample instants: nothing is interpolated, a
25 Hz table stays 25 Hz (``meta["sample_period_s"]``, ``meta["resampled"]`` False), and
a row where a column has no value stays NaN. `split_table` cuts a table that holds many
runs into one trace per combination of key columns (``--split-by load,run,group``).

With a SYNC period (``--sync-period``) the table is resampled onto that grid (the overlap
of all mapped columns): linear interpolation, except ``mode`` (previous value); each
column's own blank/NaN rows are skipped, so channels logged at different rates in one
table are fine. Points are interpolated, not averaged.

Either way a NaN block (a run of rows where a column that usually has a value has none,
`nan_blocks`) is not interpolated over: its samples are left empty, as the lost samples
of a decoded log, and the block is listed in ``meta["nan_blocks"]`` (table rows, time
span); the HUMS and the gap diagnosis bridge short ones and refuse or leave out what
longer ones hold.

Nothing is dropped silently: an infinite value, a row without a time or a split key, a
time column with one value, and two rows at one time with different values are
BenchErrors naming the file and line (a repeated identical row is merged into one).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.signals.tables import COMPRESSED, FINITE, Rows, read_rows
from bench.signals.textlines import read_text
from bench.signals.trace import Trace
from bench.signals.units import UNITS

__all__ = ["COMPRESSED", "FINITE", "MapEntry", "Rows", "build_trace", "import_table",
           "map_columns", "read_map", "read_rows", "read_table", "split_table"]

QUANTITY = {
    "t_s": "time", "setpoint_position_m": "length", "position_m": "length",
    "setpoint_speed_rad_s": "speed", "motor_speed_rad_s": "speed",
    "motor_angle_rad": "angle", "current_a": "current", "current_demand_a": "current",
    "mode": "mode", "load_force_n": "force",
}



@dataclass(frozen=True)
class MapEntry:
    signal: str
    column: str
    unit: str
    scale: float = 1.0
    wrap: float = 0.0          # wrap period in raw table values (unwrapped), 0: none
    minus: str = ""            # a column subtracted from `column` before scaling

    @property
    def factor(self) -> float:
        return self.scale * UNITS[QUANTITY[self.signal]][self.unit]


def _entry(d: dict[str, Any], where: str) -> MapEntry:
    sig = str(d.get("signal", "")).strip()
    if sig not in QUANTITY:
        raise BenchError(f"{where}: unknown bench signal {sig!r} (signals: "
                         f"{', '.join(QUANTITY)})")
    col = d.get("column")
    if col is None or str(col).strip() == "":
        raise BenchError(f"{where}: signal {sig} has no source column")
    q = QUANTITY[sig]
    unit = str(d.get("unit", "-" if q == "mode" else "")).strip()
    if unit not in UNITS[q]:
        raise BenchError(f"{where}: unit {unit!r} is not a {q} unit for {sig} (use one of "
                         f"{', '.join(u for u in UNITS[q] if u)})")

    def num(key: str, default: float) -> float:
        v = d.get(key, default)
        if v is None or (isinstance(v, str) and not v.strip()):
            return default
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise BenchError(f"{where}: {key} of {sig} must be a number, got {v!r}") from None
        if not math.isfinite(x):
            raise BenchError(f"{where}: {key} of {sig} must be finite")
        return x

    scale = num("scale", 1.0)
    if scale == 0.0:
        raise BenchError(f"{where}: scale of {sig} is 0")
    minus = d.get("minus")
    minus = "" if minus is None else str(minus).strip()
    return MapEntry(sig, str(col).strip(), unit, scale, num("wrap", 0.0), minus)


def _json_map(path: Path, text: str) -> Any:
    """The JSON value of a map file (BenchError for bad JSON or one nested too deep)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise BenchError(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        raise BenchError(f"{path}: not a column map (nested too deep to read)") from None


def read_map(path: str | Path) -> list[MapEntry]:
    """The column map from a JSON or CSV file (BenchError naming the problem)."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such map file: {path}")
    text = read_text(path, "map")
    rows: list[dict[str, Any]]
    if path.suffix.lower() == ".json":
        data = _json_map(path, text)
        if isinstance(data, dict):
            rows = []
            for sig, v in data.items():
                rows.append({"signal": sig, **(v if isinstance(v, dict) else {"column": v})})
        elif isinstance(data, list) and all(isinstance(r, dict) for r in data):
            rows = data
        else:
            raise BenchError(f"{path}: the map must be a list of entries or an object "
                             "signal -> column")
    elif path.suffix.lower() == ".csv":
        rd = csv.DictReader(io.StringIO(text))
        if not rd.fieldnames or "signal" not in rd.fieldnames or "column" not in rd.fieldnames:
            raise BenchError(f"{path}: a CSV map needs a header signal,column,unit,scale")
        rows = list(rd)
    else:
        raise BenchError(f"{path}: the map must be .json or .csv")
    entries = [_entry(r, f"{path.name} entry {i + 1}") for i, r in enumerate(rows)]
    seen: set[str] = set()
    for e in entries:
        if e.signal in seen:
            raise BenchError(f"{path.name}: signal {e.signal} is mapped twice")
        seen.add(e.signal)
    if not entries:
        raise BenchError(f"{path}: the map is empty")
    return entries


def read_table(path: str | Path, columns: list[str]) -> dict[str, np.ndarray]:
    """The named columns of a CSV or Parquet table as float arrays (blank -> NaN)."""
    return read_rows(path, columns)[0]


def import_table(table: str | Path, mapping: list[MapEntry], sync_period_s: float | None = None,
                 source_rate_hz: float | None = None) -> Trace:
    """The mapped table as a trace: at its own sample instants (``sync_period_s`` None,
    the default), or resampled to a SYNC grid of that period (see module doc)."""
    by_sig = {e.signal: e for e in mapping}
    raw, rows = read_rows(table, map_columns(mapping))
    return build_trace(raw, by_sig, str(table), sync_period_s, source_rate_hz, rows)


def map_columns(mapping: list[MapEntry]) -> list[str]:
    """Every table column the map reads."""
    return sorted({e.column for e in mapping} | {e.minus for e in mapping if e.minus})


def split_table(table: str | Path, mapping: list[MapEntry], keys: list[str],
                sync_period_s: float | None = None,
                source_rate_hz: float | None = None) -> list[tuple[str, Trace]]:
    """One trace per combination of the `keys` columns' values (a table holding many
    runs), in the order the combinations first appear; each named ``k1=v1_k2=v2``."""
    if not keys:
        raise BenchError("--split-by names no column")
    by_sig = {e.signal: e for e in mapping}
    if "t_s" in by_sig and by_sig["t_s"].column in keys:
        raise BenchError(f"--split-by {by_sig['t_s'].column}: that is the table's time column "
                         "(t_s in the map), not a key of a run; split by the columns that "
                         "tell the runs apart (e.g. load,run,group)")
    raw, where = read_rows(table, sorted(set(map_columns(mapping)) | set(keys)))
    kv = np.column_stack([raw[k] for k in keys])
    bad = ~np.isfinite(kv).all(axis=1)
    if bad.all():
        raise BenchError(f"{table}: the split column(s) {', '.join(keys)} have no values")
    if bad.any():
        idx = np.flatnonzero(bad)
        raise BenchError(f"{table}: {len(idx)} row(s) without a value in the split "
                         f"column(s) {', '.join(keys)} ({where.some(idx)}): fill in the "
                         "key or delete the row(s)")
    _, first, inverse = np.unique(kv, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    out = []
    for g in np.argsort(first):
        rows = inverse == g
        vals = kv[first[g]]
        name = "_".join(f"{k}={_key_text(v)}" for k, v in zip(keys, vals, strict=True))
        part = {c: v[rows] for c, v in raw.items()}
        try:
            tr = build_trace(part, by_sig, str(table), sync_period_s, source_rate_hz,
                             where.take(rows))
        except BenchError as exc:
            raise BenchError(f"{name}: {exc}") from None
        tr.meta["split"] = {k: float(v) for k, v in zip(keys, vals, strict=True)}
        out.append((name, tr))
    return out


def _key_text(v: float) -> str:
    """A split key's value in a file name: 20 -> '20', -40 -> '-40', 2.5 -> '2.5',
    100.0001 -> '100.0001' (the shortest text that reads back as the same number, so
    distinct keys keep distinct names)."""
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e16 else repr(v)


def build_trace(raw: dict[str, np.ndarray], by_sig: dict[str, MapEntry], source: str,
                sync_period_s: float | None, source_rate_hz: float | None,
                rows: Rows | None = None) -> Trace:
    """The trace of the table columns `raw` (see `import_table`); `rows`: where they are
    in the table file (default: data row i on line i + 2 of `source`)."""
    if sync_period_s is not None and not (1e-5 <= sync_period_s <= 1.0):
        raise BenchError("the SYNC period must be between 10 us and 1 s")
    if rows is None:
        rows = Rows(Path(source), np.arange(len(next(iter(raw.values())))) + 2)
    _check_types(by_sig, rows)
    t = _time_column(raw, by_sig, source_rate_hz, rows)
    values = {sig: _values(raw, e, rows) for sig, e in by_sig.items() if sig != "t_s"}
    if not values:
        raise BenchError("the map maps no signal besides time")
    _within_measurement(values, by_sig, rows)
    first = _same_time(t, values, by_sig, rows)
    if sync_period_s is None:
        return _native(values, by_sig, t, source, first, rows)
    series = {}
    holes: dict[str, list[tuple[int, int, float, float]]] = {}
    for sig, y in values.items():
        e = by_sig[sig]
        ok = np.isfinite(y) & np.isfinite(t)
        holes[sig] = nan_blocks(ok, t)
        series[sig] = _signal_series(sig, e, t, y, ok, rows)
    t0 = max(ts[0] for ts, _ in series.values())
    t1 = min(ts[-1] for ts, _ in series.values())
    if t1 - t0 < sync_period_s:
        raise BenchError("the mapped columns do not overlap in time")
    grid = t0 + np.arange(int(math.floor((t1 - t0) / sync_period_s + 1e-9)) + 1) * sync_period_s
    out = {sig: _resample(sig, ts, ys, grid) for sig, (ts, ys) in series.items()}
    blocks = _blank_holes(out, holes, by_sig, grid, t0)
    out["t_s"] = grid - grid[0]
    meta = {"source": source, "imported": True, "sync_period_s": sync_period_s,
            "sample_period_s": sync_period_s, "resampled": True,
            "time_offset_s": float(t0),
            "map": [e.__dict__ for e in by_sig.values()], "nan_blocks": blocks}
    return Trace(out, meta)


def _values(raw: dict[str, np.ndarray], e: MapEntry, rows: Rows) -> np.ndarray:
    """One mapped signal in SI: (column - minus column) x scale x unit factor; a value
    that is finite in the table but not once scaled (1e308 kgf) is a BenchError naming
    its column and line."""
    with np.errstate(over="ignore", invalid="ignore"):
        y = (raw[e.column] - raw[e.minus] if e.minus else raw[e.column]) * e.factor
    given = np.isfinite(raw[e.column]) & (np.isfinite(raw[e.minus]) if e.minus else True)
    bad = np.flatnonzero(given & ~np.isfinite(y))
    if len(bad):
        k = int(bad[0])
        raw_v = f"{raw[e.column][k]:g}" + (f" - {raw[e.minus][k]:g}" if e.minus else "")
        raise BenchError(f"{rows.at(k)}: column {e.column!r} ({e.signal}): {raw_v} "
                         f"{e.unit or '-'} x {e.scale:g} is beyond the range of a number in "
                         f"SI units ({len(bad)} row(s)); {FINITE}")
    return y


def _check_types(by_sig: dict[str, MapEntry], rows: Rows) -> None:
    """A timestamp or duration column (Parquet; read in seconds, `bench.signals.tables`)
    maps only to the time t_s, with unit s and scale 1: any other use is a BenchError
    naming the column."""
    for sig, e in by_sig.items():
        for col in (e.column, e.minus):
            if col not in rows.timestamps:
                continue
            if sig != "t_s" or col == e.minus:
                raise BenchError(f"{rows.path}: column {col!r} holds timestamps (a Parquet "
                                 f"timestamp or duration), not values of {sig}; map it to "
                                 "t_s only")
            if e.unit != "s" or e.scale != 1.0:
                raise BenchError(f"{rows.path}: column {col!r} holds timestamps (a Parquet "
                                 "timestamp or duration), read in seconds whatever its own "
                                 f"unit: map it with unit s and scale 1 (not {e.unit!r} x "
                                 f"{e.scale:g})")


def _forward(t: np.ndarray, where: Rows, rows: np.ndarray | None, what: str, hint: str
             ) -> np.ndarray:
    """The steps of `t`; a BenchError at the first step back, naming its data row (`t`'s
    sample k is data row `rows[k]`, or k without `rows`)."""
    d = np.diff(t)
    if np.any(d < 0):
        k = int(np.argmax(d < 0)) + 1
        row = k if rows is None else int(rows[k])
        raise BenchError(f"{where.path}: time goes backwards in the table{what} at "
                         f"{where.word} {int(where.numbers[row])} ({hint})")
    return d


def _native(values: dict[str, np.ndarray], by_sig: dict[str, MapEntry], t: np.ndarray,
            source: str, kept: np.ndarray, where: Rows) -> Trace:
    """The trace at the table's own sample instants (`kept`: the rows that do not
    repeat the time of the row before): no interpolation; a row a signal has no value
    in stays NaN (its blocks listed as in the resampled case)."""
    if len(t) < 2:
        raise BenchError(f"{where.path}: the table has fewer than 2 rows with a time")
    _forward(t, where, None, "", "sort the table first, or split it: --split-by")
    rows = np.flatnonzero(kept)
    ts = t[rows]
    out: dict[str, np.ndarray] = {}
    blocks = []
    for sig, y in values.items():
        e = by_sig[sig]
        ys = y[rows]
        ok = np.isfinite(ys)
        if ok.sum() < 2:
            raise BenchError(f"{where.path}: column {e.column!r} ({sig}) has fewer than 2 "
                             "values")
        if e.wrap:
            ys[ok] = np.unwrap(ys[ok], period=abs(e.wrap * e.factor))
        if sig == "mode":
            ys = np.round(ys)
        out[sig] = ys
        for first, n, ta, tb in nan_blocks(ok, ts):
            blocks.append({"signal": sig, "column": e.column, "first_row": int(rows[first]) + 1,
                           "last_row": int(rows[first + n - 1]) + 1, "rows": n,
                           "t0_s": float(ta - ts[0]), "t1_s": float(tb - ts[0]),
                           "samples": n})
    out["t_s"] = ts - ts[0]
    meta = {"source": source, "imported": True, "resampled": False,
            "sample_period_s": float(np.median(np.diff(ts))), "time_offset_s": float(ts[0]),
            "map": [e.__dict__ for e in by_sig.values()], "nan_blocks": blocks}
    return Trace(out, meta)


def _time_column(raw: dict[str, np.ndarray], by_sig: dict[str, MapEntry],
                 source_rate_hz: float | None, where: Rows) -> np.ndarray:
    """The table's time in s: its mapped t_s column (a value in every row, not the same
    in all), else rows at `source_rate_hz`."""
    n = len(next(iter(raw.values())))
    if "t_s" in by_sig:
        e = by_sig["t_s"]
        if source_rate_hz:
            raise BenchError(f"--source-rate is for a table without a time column; the map "
                             f"takes t_s from column {e.column!r} (drop one of the two)")
        t = _values(raw, e, where)
        idx = np.flatnonzero(~np.isfinite(t))
        if len(idx):
            raise BenchError(f"{where.path}: {len(idx)} row(s) without a time in column "
                             f"{e.column!r} ({where.some(idx)}): every row needs its time; "
                             "fill it in or delete the row(s)")
        if n >= 2 and np.all(t == t[0]):
            raise BenchError(f"{where.path}: every row has the same time in column "
                             f"{e.column!r} ({raw[e.column][0]:g} {e.unit}): the time column "
                             "must increase (is t_s mapped to the table's time column?)")
        return t
    if source_rate_hz:
        if source_rate_hz <= 0:
            raise BenchError("the source rate must be > 0 Hz")
        return np.arange(n) / source_rate_hz
    raise BenchError("the map has no time signal t_s; map the table's time column or "
                     "give the table's fixed rate (--source-rate)")


def _within_measurement(values: dict[str, np.ndarray], by_sig: dict[str, MapEntry],
                        where: Rows) -> None:
    """No imported value beyond any measurement (|SI value| > `trace.MAX_VALUE`): every
    reader refuses such a trace, so the import does, naming the column and the rows."""
    from bench.signals.trace import MAX_VALUE
    for sig, y in values.items():
        idx = np.flatnonzero(np.abs(np.nan_to_num(y, nan=0.0)) > MAX_VALUE)
        if len(idx):
            e = by_sig[sig]
            raise BenchError(f"{where.path}: column {e.column!r} ({sig}) holds {y[idx[0]]:g} "
                             f"in {len(idx)} row(s) ({where.some(idx)}), beyond any "
                             f"measurement (|value| > {MAX_VALUE:g} in SI units)")


def _same_time(t: np.ndarray, values: dict[str, np.ndarray], by_sig: dict[str, MapEntry],
               where: Rows) -> np.ndarray:
    """The rows that do not repeat the time of the row before. A row that does is merged
    into the first row of its time: a value that row lacks is taken from it (`values`
    changed in place); a repeated row is harmless, but a different value at the same
    time is a BenchError naming both lines (one of them would be lost)."""
    dup = np.flatnonzero(np.diff(t) == 0) + 1
    first = np.ones(len(t), bool)
    first[dup] = False
    if not len(dup):
        return first
    start = np.maximum.accumulate(np.where(first, np.arange(len(t)), 0))
    for sig, y in values.items():
        for j in dup[np.isfinite(y[dup])]:
            k = start[j]
            if np.isnan(y[k]):
                y[k] = y[j]
            elif y[k] != y[j]:
                raise BenchError(
                    f"{where.path} {where.word}s {int(where.numbers[k])} and "
                    f"{int(where.numbers[j])}: the same time ({t[j]:g} s) with different "
                    f"values in column {by_sig[sig].column!r} ({sig}); a time must name one "
                    "sample: delete or correct one of the rows")
    return first


def _signal_series(sig: str, e: MapEntry, t: np.ndarray, y: np.ndarray,
                   ok: np.ndarray, where: Rows) -> tuple[np.ndarray, np.ndarray]:
    """(times, values) of one mapped signal's valid rows: time must not go backwards,
    repeated times keep their first row, wrapped angles are unwrapped."""
    ts, ys = t[ok], y[ok]
    if len(ts) < 2:
        raise BenchError(f"column {e.column!r} ({sig}) has fewer than 2 values")
    d = _forward(ts, where, np.flatnonzero(ok), f" for {e.column!r}", "sort the table first")
    if np.any(d == 0):
        keep = np.concatenate([[True], d > 0])
        ts, ys = ts[keep], ys[keep]
    if e.wrap:
        ys = np.unwrap(ys, period=abs(e.wrap * e.factor))
    return ts, ys


def _resample(sig: str, ts: np.ndarray, ys: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """One signal on the SYNC grid: the mode held (zero-order), the others interpolated."""
    if sig == "mode":
        idx = np.clip(np.searchsorted(ts, grid, side="right") - 1, 0, len(ts) - 1)
        return np.round(ys[idx])
    return np.interp(grid, ts, ys)


def _blank_holes(out: dict[str, np.ndarray], holes: dict[str, list[tuple[int, int, float, float]]],
                 by_sig: dict[str, MapEntry], grid: np.ndarray, t0: float) -> list[dict[str, Any]]:
    """NaN the grid samples inside each signal's missing-row blocks (in `out`); the
    blocks that cover a sample, as the trace's `nan_blocks` metadata."""
    blocks = []
    for sig, found in holes.items():
        for first, rows, ta, tb in found:
            inside = (grid > ta) & (grid < tb)
            if not inside.any():
                continue
            out[sig][inside] = np.nan
            blocks.append({"signal": sig, "column": by_sig[sig].column,
                           "first_row": first + 1, "last_row": first + rows, "rows": rows,
                           "t0_s": float(ta - t0), "t1_s": float(tb - t0),
                           "samples": int(inside.sum())})
    return blocks


def nan_blocks(ok: np.ndarray, t: np.ndarray) -> list[tuple[int, int, float, float]]:
    """Runs of rows where a column has no value although it usually has one: its valid
    rows more than twice their median row spacing apart (a channel logged at a lower
    rate, or one missing row now and then, is no block). Each as (first missing data row,
    0-based; rows; time of the valid sample before; time of the one after)."""
    rows = np.flatnonzero(ok)
    if len(rows) < 3:
        return []
    d = np.diff(rows)
    med = float(np.median(d))
    return [(int(rows[k] + 1), int(d[k] - 1), float(t[rows[k]]), float(t[rows[k + 1]]))
            for k in np.flatnonzero(d > 2 * med)]

