"""A rig's table -> motion cycles, each split into set-point phases.

A rig's table (CSV, optionally xz/gz/bz2-compressed, or Parquet) holds one row per sample
with a set-point, the measured position (or the position error), the motor current, and
the keys of the run: load, run number and cycle (`group`). The Cranfield linear-actuator
data set uses exactly these columns (set_point and position_error in mm, current in A,
load in kgf, run, group, time restarting at 0 for every cycle). A trace written by
`bench import` (`.npz`, with `setpoint_position_m`, `position_m`, `current_a`) is read
too (one per run or per cycle, from `bench import --split-by load,run[,group]`); its
load, run and cycle come from the split keys in its metadata.

Nothing is resampled: a cycle keeps the samples the rig logged. The phases come from the
set-point alone (`phases`): out-stroke, in-stroke and the dwells between them; within a
stroke the acceleration, constant-speed and deceleration parts.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.signals import estimators as E
from bench.signals.tables import COMPRESSED, file_suffixes, read_table

# the signals a cycle needs and the Cranfield table's column for each
DEFAULT_COLUMNS: dict[str, str] = {
    "setpoint": "set_point", "position_error": "position_error", "current": "current",
    "load": "load", "run": "run", "group": "group", "time": "time",
}
RIG_FORMATS = (".csv", ".parquet")
"""The rig tables `read_columns` reads (CSV also compressed; a trace is also .npz)."""
SUFFIXES = file_suffixes((*RIG_FORMATS, ".npz"))
MOVING_FRACTION = 0.02     # |set-point step| above this share of the largest step: moving
RAMP_FRACTION = 0.9        # |set-point speed| below this share of the stroke's median: ramp


@dataclass
class Cycle:
    """One motion cycle as logged: positions in mm, current in A, time in s."""
    t_s: np.ndarray
    setpoint_mm: np.ndarray
    position_mm: np.ndarray
    current_a: np.ndarray
    load: float                 # in the table's unit (kgf for Cranfield)
    run: int
    group: int
    source: str                 # the file's condition name (e.g. spalling8)
    meta: dict[str, Any] = field(default_factory=dict)
    load_unit: str = ""         # the unit of `load` ("" unknown: a rig's own table)
    _memo: dict[str, Any] = field(default_factory=dict, init=False, repr=False,
                                  compare=False)

    def memo(self, name: str, compute: Any) -> Any:
        """`compute()` once per cycle (a cycle is scored against several baselines): its
        value is kept until one of the cycle's signal arrays is replaced (an array is
        not changed in place after it is read)."""
        key = (id(self.setpoint_mm), id(self.position_mm), id(self.current_a))
        hit = self._memo.get(name)
        if hit is None or hit[0] != key:
            hit = self._memo[name] = (key, compute())
        return hit[1]

    def __getstate__(self) -> dict[str, Any]:
        """Pickled (to a worker) without the memo: it is keyed by the arrays' identities,
        which a copy does not keep."""
        state = dict(self.__dict__)
        state["_memo"] = {}
        return state

    def segments(self) -> list[Segment]:
        """`phases` of the cycle's set-point, computed once."""
        return self.memo("segments", lambda: phases(self.setpoint_mm))

    def ramps(self, seg: Segment) -> dict[str, slice]:
        """`ramps` of one of the cycle's segments, computed once."""
        return self.memo(f"ramps.{seg.name}.{seg.start}.{seg.stop}",  # type: ignore[no-any-return]
                         lambda: ramps(self.setpoint_mm, seg))

    @property
    def position_error_mm(self) -> np.ndarray:
        return self.setpoint_mm - self.position_mm

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def label(self) -> str:
        load = f"{self.load:g}" if math.isfinite(self.load) else "unknown"
        return f"{self.source} load {load} run {self.run} cycle {self.group}"


@dataclass(frozen=True)
class Segment:
    """One set-point phase of a cycle: samples [start, stop)."""
    name: str            # out, in, dwell_top, dwell_bottom (a second one: out_2 ...)
    start: int
    stop: int
    direction: int       # +1 out, -1 in, 0 dwell

    def __len__(self) -> int:
        return self.stop - self.start


def condition_name(path: str | Path) -> str:
    """The file's name without its table suffixes: spalling8.csv.xz -> spalling8."""
    name = Path(path).name
    for suf in sorted(SUFFIXES, key=len, reverse=True):
        if name.lower().endswith(suf):
            return name[: -len(suf)]
    return Path(path).stem


_STAGE = re.compile(r"^([A-Za-z]+)(\d+)(?!\d)")
"""A condition's stage: the number that ends its leading word (spalling8,
spalling5_load40_runs1-2 -> 5), not a number further on (the load, the runs)."""


def stage_number(condition: str) -> int | None:
    """The stage of a condition name (spalling8 -> 8, spalling5_load40_runs1-2 -> 5), None
    when the name does not start with a word and its number (normal_runs1-4)."""
    m = _STAGE.match(condition)
    return int(m.group(2)) if m else None


def condition_family(condition: str) -> str:
    """The name less its stage number (spalling5_load40_runs1-2 -> spalling#_load40_runs1-2):
    the stages of one family share it."""
    m = _STAGE.match(condition)
    return f"{m.group(1)}#{condition[m.end():]}" if m else condition


def read_columns(path: str | Path, text: dict[str, np.ndarray] | None = None
                 ) -> dict[str, np.ndarray]:
    """Every numeric column of a CSV (plain or xz/gz/bz2) or Parquet table
    (`bench.signals.tables.read_table`); a column that is not all numbers (the Cranfield table's
    text column `profile`, or a number column with a text cell) is left out, or put in
    `text` (when given) as its cells' strings (None for a blank cell)."""
    tab = read_table(path, formats=RIG_FORMATS, text=True)
    if text is not None:
        text.update(tab.text)
    return tab.columns


def _decompressed(path: Path) -> bytes:
    with COMPRESSED.get(path.suffix.lower(), open)(path, "rb") as fh:
        data: bytes = fh.read()
    return data


MIN_SAMPLES = 8          # a cycle shorter than this is not read
KEYS = ("load", "run", "group")
# a text cell that means "no value" (pyarrow's own missing-value markers), not a bad cell
MISSING = {"", "na", "n/a", "nan", "-nan", "null", "none", "#n/a", "#na"}


def read_cycles(path: str | Path, columns: dict[str, str] | None = None,
                skipped: list[str] | None = None) -> list[Cycle]:
    """The motion cycles of a rig's table or of a `bench import` trace, in file order. A
    cycle of fewer than `MIN_SAMPLES` samples, with a sample without set-point, position
    or current, with a row without its load, run or cycle number, or whose time does not
    advance, is not read (a row that repeats the one before it exactly is dropped);
    `skipped` (when given) gets one line per such cycle, row or cell saying why, so that a
    caller reports it instead of losing it silently. BenchError, with the first reasons,
    when no cycle is left."""
    path = Path(path)
    lost: list[str] = []
    if path.name.lower().endswith(".npz"):
        out = _trace_cycles(path, lost)
    else:
        out = _table_cycles(path, dict(DEFAULT_COLUMNS, **(columns or {})), lost)
    if skipped is not None:
        skipped += lost
    if not out:
        more = f"; and {len(lost) - 3} more" if len(lost) > 3 else ""
        why = f" ({'; '.join(lost[:3])}{more})" if lost else ""
        raise BenchError(f"{path}: no complete motion cycle in the table{why}")
    return out


def line_of(path: Path, row: int) -> str:
    """Where data row `row` (from 0) of a table is: 'line N' of a CSV, counting the blank
    lines the reader skips (`_data_lines`), 'row N' of a Parquet table."""
    if path.name.lower().endswith(".parquet"):
        return f"row {row + 1}"
    try:
        st = path.stat()
        lines = _data_lines(str(path), st.st_mtime_ns, st.st_size)
    except OSError:
        lines = ()
    return f"line {lines[row] if row < len(lines) else row + 2}"


@functools.lru_cache(maxsize=4)
def _data_lines(path: str, mtime_ns: int, size: int) -> tuple[int, ...]:
    """The file line of each data row of a CSV (from 1; the header's line is not one):
    pyarrow's reader skips empty lines, so row k is the k-th non-empty row after the
    header. Only read for a message (the file's time and size key the cache)."""
    text = _decompressed(Path(path)).decode("utf-8", errors="replace")
    rd = csv.reader(io.StringIO(text))
    starts: list[int] = []
    prev = 0
    for row in rd:
        if row:                           # [] for an empty line
            starts.append(prev + 1)
        prev = rd.line_num
    return tuple(starts[1:])


def _table_cycles(path: Path, cols: dict[str, str], lost: list[str]) -> list[Cycle]:
    """`read_cycles` of a rig's own table (CSV or Parquet)."""
    text: dict[str, np.ndarray] = {}
    raw = read_columns(path, text)
    if is_trace(path, raw):
        return _trace_cycles(path, lost)          # a bench trace, not a rig table
    for name in sorted(set(cols.values()) | {cols.get("position", "position")}):
        if name in text:                          # a needed column with a text cell
            raw[name] = _numbers(path, name, text[name], lost)
    missing = [cols[k] for k in ("setpoint", "current") if cols[k] not in raw]
    if cols["position_error"] not in raw and cols.get("position", "position") not in raw:
        missing.append(f"{cols['position_error']} (or a position column)")
    if missing:
        raise BenchError(f"{path}: the table has no column(s) {', '.join(missing)} "
                         f"(it has: {', '.join(sorted(raw))})")
    sp = raw[cols["setpoint"]]
    if not len(sp):
        raise BenchError(f"{path}: the table has no rows (a header only)")
    keys: dict[str, np.ndarray | None] = {k: raw.get(cols[k]) for k in KEYS}
    for k, x in keys.items():
        if x is not None and not np.isfinite(x).any():
            raise BenchError(f"{path}: column {cols[k]} has no number in any row")
    if keys["load"] is None:
        lost.append(f"{path.name}: no {cols['load']} column: the cycles' load is unknown")
    return _split(path, cols, raw, text, keys, lost)


def _numbers(path: Path, name: str, cells: np.ndarray, lost: list[str]) -> np.ndarray:
    """A needed column that came as text: its numbers; NaN (missing) for a blank cell and
    for a cell that is not a number, the latter listed in `lost` with its line."""
    out = np.full(len(cells), np.nan)
    bad = []
    for i, x in enumerate(cells):
        if x is None or x.strip().lower() in MISSING:
            continue
        try:
            out[i] = float(x)
        except ValueError:
            bad.append(i)
    if bad:
        first = ", ".join(f"{line_of(path, i)}: {cells[i]!r}" for i in bad[:3])
        more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
        lost.append(f"{path.name}: column {name}: {len(bad)} cell(s) not a number "
                    f"({first}{more}): read as missing")
    return out


def _split(path: Path, cols: dict[str, str], raw: dict[str, np.ndarray],
           text: dict[str, np.ndarray], keys: dict[str, np.ndarray | None],
           lost: list[str]) -> list[Cycle]:
    """The table's rows split into cycles where the cycle number changes (a row without
    one stays with the rows before it, and its cycle is not read)."""
    sp = raw[cols["setpoint"]]
    pos = (sp - raw[cols["position_error"]] if cols["position_error"] in raw
           else raw[cols.get("position", "position")])
    cur = raw[cols["current"]]
    time = raw.get(cols["time"])
    group = _filled(keys["group"]) if keys["group"] is not None else cycle_numbers(sp)
    starts = np.flatnonzero(np.r_[True, np.diff(group) != 0])
    bounds = [int(x) for x in starts] + [len(sp)]
    source = condition_name(path)
    out: list[Cycle] = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=False):
        load, run = (_first(keys[k], a, b) for k in ("load", "run"))
        label = (f"{source} load {_g(load)} run {_g(0.0 if keys['run'] is None else run)} "
                 f"cycle {_g(group[a])}")
        why = _bad_keys(path, cols, keys, text, a, b)
        rows, notes, why = (np.arange(a, b), [], why) if why else \
            _repeats(path, raw, text, time, a, b)
        if why:
            lost.append(f"{label}: {why}: not read")
            continue
        lost += [f"{label}: {x}" for x in notes]
        t = time[rows] - time[rows[0]] if time is not None else np.arange(len(rows), dtype=float)
        cyc = Cycle(t, sp[rows], pos[rows], cur[rows], load,
                    0 if keys["run"] is None else int(run), int(group[a]), source)
        _keep(cyc, out, lost)
    return out


def _g(x: float) -> str:
    return f"{int(x)}" if math.isfinite(x) and x == int(x) else (
        f"{x:g}" if math.isfinite(x) else "?")


def _first(x: np.ndarray | None, a: int, b: int) -> float:
    """The first finite value of x[a:b] (NaN: none, or no column)."""
    if x is None:
        return float("nan")
    ok = np.flatnonzero(np.isfinite(x[a:b]))
    return float(x[a + ok[0]]) if len(ok) else float("nan")


def _filled(x: np.ndarray) -> np.ndarray:
    """`x` with each missing value replaced by the one before it (at the start: the first
    one there is)."""
    ok = np.isfinite(x)
    if ok.all():
        return x
    idx = np.where(ok, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    y = x[idx]
    first = int(np.flatnonzero(ok)[0])
    y[:first] = x[first]
    return y


def _bad_keys(path: Path, cols: dict[str, str], keys: dict[str, np.ndarray | None],
              text: dict[str, np.ndarray], a: int, b: int) -> str:
    """Why rows a..b-1 cannot be one cycle ("" they can): a row without its load, run or
    cycle number (blank, or a text cell), or a row without a cycle number just before them
    (it may be this cycle's first)."""
    for k in KEYS:
        x = keys[k]
        if x is None:
            continue
        bad = np.flatnonzero(~np.isfinite(x[a:b]))
        if len(bad):
            r = a + int(bad[0])
            cell = text[cols[k]][r] if cols[k] in text else None
            what = (f"{k} {cell!r} is not a number" if cell is not None
                    and cell.strip().lower() not in MISSING else f"no {k}")
            return f"{what} at {line_of(path, r)}"
    g = keys["group"]
    if g is not None and a > 0 and not np.isfinite(g[a - 1]):
        return f"no group at {line_of(path, a - 1)}, just before the cycle"
    return ""


def _repeats(path: Path, raw: dict[str, np.ndarray], text: dict[str, np.ndarray],
             time: np.ndarray | None, a: int, b: int) -> tuple[np.ndarray, list[str], str]:
    """The rows of the cycle a..b-1 to read, notes, and why it cannot be read ("" it can):
    a row that repeats the one before it exactly (its time too) is dropped with a note; a
    time that does not advance otherwise makes the cycle unreadable (its samples would be
    split into phases at a step the rig never made)."""
    rows = np.arange(a, b)
    if time is None:
        return rows, [], ""
    same = (np.flatnonzero(np.diff(time[a:b]) == 0) + a + 1).tolist()
    drop: list[int] = []
    notes: list[str] = []
    for r in same:
        if all(x[r] == x[r - 1] or (x[r] != x[r] and x[r - 1] != x[r - 1])
               for x in raw.values()) and all(x[r] == x[r - 1] for x in text.values()):
            drop.append(int(r))
            notes.append(f"{line_of(path, r)} repeats {line_of(path, r - 1)} exactly: "
                         "dropped (the cycle is read without it)")
        else:
            return rows, [], (f"time does not advance at {line_of(path, r)} ({time[r]:g}, "
                              f"as at {line_of(path, r - 1)})")
    return (np.setdiff1d(rows, drop) if drop else rows), notes, ""


def is_trace(path: str | Path, raw: dict[str, Any] | None = None) -> bool:
    """True for a `bench import` trace (.npz, or Parquet with the bench's signal names),
    False for a rig's own table."""
    name = Path(path).name.lower()
    if name.endswith(".npz"):
        return True
    if not name.endswith(".parquet"):
        return False
    return "setpoint_position_m" in (raw if raw is not None else read_columns(Path(path)))


def _keep(cyc: Cycle, out: list[Cycle], skipped: list[str] | None) -> None:
    """`cyc` appended to `out`, or the reason it is not read appended to `skipped`."""
    why = unreadable(cyc)
    if not why:
        out.append(cyc)
    elif skipped is not None:
        skipped.append(f"{cyc.label}: {why}: not read")


def unreadable(cyc: Cycle) -> str:
    """Why a cycle cannot be used at all ("" it can): too short, or samples without a
    value (a gap in the log; nothing is interpolated)."""
    if len(cyc) < MIN_SAMPLES:
        return f"{len(cyc)} sample(s), fewer than {MIN_SAMPLES}"
    bad = [f"{int(np.count_nonzero(~np.isfinite(x)))} without {name}"
           for name, x in (("set-point", cyc.setpoint_mm), ("position", cyc.position_mm),
                           ("current", cyc.current_a)) if not np.isfinite(x).all()]
    return f"samples {', '.join(bad)}" if bad else ""


def _trace_cycles(path: Path, skipped: list[str] | None = None) -> list[Cycle]:
    """Cycles of a `bench import` trace file (metres -> mm), split by set-point."""
    from bench.signals.trace import Trace
    return cycles_from_trace(Trace.load(path), condition_name(path), skipped=skipped)


def cycles_from_trace(tr: Any, name: str, run: int | None = None,
                      skipped: list[str] | None = None) -> list[Cycle]:
    """Cycles of a trace (`bench.signals.trace.Trace`, metres -> mm): one per `group` key of a
    `bench import --split-by` trace, else split where an out-stroke starts. The load and
    the run come from the split keys (the table's own units), else the metadata, else
    the median logged load (N, 3 significant digits) and `run`."""
    tr.require(("setpoint_position_m", "position_m", "current_a"), "a rig baseline")
    sp = tr["setpoint_position_m"] * 1e3
    pos = tr["position_m"] * 1e3
    keys = tr.meta.get("split") or {}            # `bench import --split-by` keys
    group = (np.full(len(sp), float(keys["group"])) if "group" in keys
             else cycle_numbers(sp))
    load = float(keys.get("load", tr.meta.get("load", _logged_load(tr))))
    run_no = int(keys.get("run", tr.meta.get("run", 0 if run is None else run)))
    unit = load_unit(tr.meta)
    out: list[Cycle] = []
    for g in np.unique(group):
        m = group == g
        _keep(Cycle(tr.t[m] - tr.t[m][0], sp[m], pos[m], tr["current_a"][m], load,
                    run_no, int(g), str(tr.meta.get("source_name", name)),
                    dict(tr.meta), unit), out, skipped)
    return out


def _logged_load(tr: Any) -> float:
    """The median logged load (N, rounded to 3 significant digits), NaN without one."""
    if "load_force_n" not in tr:
        return float("nan")
    f = np.asarray(tr["load_force_n"], float)
    f = f[np.isfinite(f)]
    if not len(f):
        return float("nan")
    med = float(np.median(f))
    return float(f"{med:.3g}")


def load_unit(meta: dict[str, Any]) -> str:
    """The unit of a trace's `load` split key: the import map's unit for that column
    ("" when unknown; "N" for a load taken from the logged load_force_n)."""
    keys = meta.get("split") or {}
    if "load" not in keys:
        return "" if "load" in meta else "N"
    for entry in meta.get("map") or []:
        if isinstance(entry, dict) and entry.get("column") == "load":
            return str(entry.get("unit", ""))
    return ""


def cycle_numbers(sp: np.ndarray) -> np.ndarray:
    """A cycle number per sample when the table has none: a cycle starts where an
    out-stroke starts (after a dwell or an in-stroke)."""
    lab = direction_labels(sp)
    starts = (lab == 1) & (np.r_[0, lab[:-1]] != 1)
    return np.maximum(np.cumsum(starts), 1).astype(float)


def direction_labels(sp: np.ndarray) -> np.ndarray:
    """+1 where the set-point moves out (increasing), -1 in, 0 dwell; sample k is labelled
    by the step from k to k+1 (the last sample by the step before it)."""
    d = np.diff(sp)
    if not len(d):
        return np.zeros(len(sp), int)
    lab = E.motion_direction(d, E.moving_threshold(d, MOVING_FRACTION))
    return np.r_[lab, lab[-1]].astype(int)


def phases(sp: np.ndarray) -> list[Segment]:
    """The set-point phases of a cycle in order: strokes (out / in) and dwells (a dwell
    after an out-stroke is at the top: dwell_top; after an in-stroke, or before the first
    out-stroke: dwell_bottom)."""
    lab = direction_labels(sp)
    cuts = np.flatnonzero(np.diff(lab)) + 1
    bounds = [0, *cuts.tolist(), len(sp)]
    segs: list[Segment] = []
    seen: dict[str, int] = {}
    for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=False)):
        d = int(lab[a])
        if d == 1:
            name = "out"
        elif d == -1:
            name = "in"
        else:
            before = int(lab[bounds[i - 1]]) if i else 0
            after = int(lab[b]) if b < len(sp) else 0
            name = "dwell_top" if (before == 1 or (before == 0 and after == -1)) \
                else "dwell_bottom"
        seen[name] = seen.get(name, 0) + 1
        if seen[name] > 1:
            name = f"{name}_{seen[name]}"
        segs.append(Segment(name, a, b, d))
    return segs


def ramps(sp: np.ndarray, seg: Segment) -> dict[str, slice]:
    """A stroke's acceleration, constant-speed and deceleration parts (absolute sample
    slices; a ramp shorter than one sample step is empty)."""
    if not len(seg):
        return {"accel": slice(seg.start, seg.start), "constant": slice(seg.start, seg.start),
                "decel": slice(seg.start, seg.start)}
    from bench.rig.kernels import ramp_bounds  # compiled: imported where cycles are cut
    # |np.gradient| of the stroke's set-point against RAMP_FRACTION of its median
    a, b = 0, 1                                 # one sample: at full speed
    if len(seg) > 1:
        a, b = ramp_bounds(np.asarray(sp[seg.start:seg.stop], np.float64), RAMP_FRACTION)
    a, b = int(a), int(b)
    return {"accel": slice(seg.start, seg.start + a),
            "constant": slice(seg.start + a, seg.start + b),
            "decel": slice(seg.start + b, seg.stop)}
