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

import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError

# the signals a cycle needs and the Cranfield table's column for each
DEFAULT_COLUMNS: dict[str, str] = {
    "setpoint": "set_point", "position_error": "position_error", "current": "current",
    "load": "load", "run": "run", "group": "group", "time": "time",
}
SUFFIXES = (".csv", ".csv.xz", ".csv.gz", ".csv.bz2", ".parquet", ".npz")
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

    @property
    def position_error_mm(self) -> np.ndarray:
        return self.setpoint_mm - self.position_mm

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def label(self) -> str:
        return f"{self.source} load {self.load:g} run {self.run} cycle {self.group}"


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


def stage_number(condition: str) -> int | None:
    """The trailing number of a condition name (spalling8 -> 8), None without one."""
    m = re.search(r"(\d+)$", condition)
    return int(m.group(1)) if m else None


def read_columns(path: str | Path) -> dict[str, np.ndarray]:
    """Every numeric column of a CSV (plain or xz/gz/bz2) or Parquet table; text columns
    are dropped (the Cranfield table's `profile`)."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such table: {path}")
    low = path.name.lower()
    try:
        if low.endswith(".parquet"):
            import pyarrow.parquet as pq
            table = pq.read_table(path)
        elif low.endswith((".csv", ".csv.xz", ".csv.gz", ".csv.bz2")):
            import pyarrow.csv as pacsv
            table = pacsv.read_csv(io.BytesIO(_decompressed(path)))
        else:
            raise BenchError(f"{path}: unknown table format (use {', '.join(SUFFIXES)})")
    except BenchError:
        raise
    except Exception as exc:  # noqa: BLE001 - pyarrow and the codecs raise many types
        raise BenchError(f"{path}: cannot read the table ({type(exc).__name__}: {exc})"
                         ) from None
    out = {}
    for name in table.column_names:
        col = table.column(name)
        try:
            out[name] = col.to_numpy(zero_copy_only=False).astype(float)
        except (ValueError, TypeError):
            continue
    return out


def _decompressed(path: Path) -> bytes:
    low = path.name.lower()
    if low.endswith(".xz"):
        import lzma
        return lzma.decompress(path.read_bytes())
    if low.endswith(".gz"):
        import gzip
        return gzip.decompress(path.read_bytes())
    if low.endswith(".bz2"):
        import bz2
        return bz2.decompress(path.read_bytes())
    return path.read_bytes()


MIN_SAMPLES = 8          # a cycle shorter than this is not read


def read_cycles(path: str | Path, columns: dict[str, str] | None = None,
                skipped: list[str] | None = None) -> list[Cycle]:
    """The motion cycles of a rig's table or of a `bench import` trace, in file order. A
    cycle of fewer than `MIN_SAMPLES` samples, or with a sample without set-point,
    position or current, is not read; `skipped` (when given) gets one line per such
    cycle saying why, so that a caller reports it instead of losing it silently."""
    path = Path(path)
    if path.name.lower().endswith(".npz"):
        return _trace_cycles(path, skipped)
    cols = dict(DEFAULT_COLUMNS, **(columns or {}))
    raw = read_columns(path)
    if is_trace(path, raw):
        return _trace_cycles(path, skipped)          # a bench trace, not a rig table
    source = condition_name(path)
    need = ["setpoint", "current"]
    missing = [cols[k] for k in need if cols[k] not in raw]
    if cols["position_error"] not in raw and cols.get("position", "position") not in raw:
        missing.append(f"{cols['position_error']} (or a position column)")
    if missing:
        raise BenchError(f"{path}: the table has no column(s) {', '.join(missing)} "
                         f"(it has: {', '.join(sorted(raw))})")
    sp = raw[cols["setpoint"]]
    pos = (sp - raw[cols["position_error"]] if cols["position_error"] in raw
           else raw[cols.get("position", "position")])
    n = len(sp)
    group = raw.get(cols["group"], cycle_numbers(sp))
    load = raw.get(cols["load"], np.full(n, np.nan))
    run = raw.get(cols["run"], np.zeros(n))
    time = raw.get(cols["time"])
    out: list[Cycle] = []
    # rows of one cycle are contiguous in the table; keep the table's order
    starts = np.flatnonzero(np.r_[True, np.diff(group) != 0,])
    bounds = list(starts) + [n]
    for a, b in zip(bounds[:-1], bounds[1:], strict=False):
        t = time[a:b] - time[a] if time is not None else np.arange(b - a, dtype=float)
        cyc = Cycle(t, sp[a:b], pos[a:b], raw[cols["current"]][a:b], float(load[a]),
                    int(run[a]), int(group[a]), source)
        _keep(cyc, out, skipped)
    if not out:
        raise BenchError(f"{path}: no complete motion cycle in the table")
    return out


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
    from bench.trace import Trace
    return cycles_from_trace(Trace.load(path), condition_name(path), skipped=skipped)


def cycles_from_trace(tr: Any, name: str, run: int | None = None,
                      skipped: list[str] | None = None) -> list[Cycle]:
    """Cycles of a trace (`bench.trace.Trace`, metres -> mm): one per `group` key of a
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
    tol = max(MOVING_FRACTION * float(np.max(np.abs(d))), 1e-12)
    lab = np.where(d > tol, 1, np.where(d < -tol, -1, 0))
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
    v = np.abs(np.gradient(sp[seg.start:seg.stop])) if len(seg) > 1 else np.zeros(len(seg))
    if not len(v):
        return {"accel": slice(seg.start, seg.start), "constant": slice(seg.start, seg.start),
                "decel": slice(seg.start, seg.start)}
    full = v >= RAMP_FRACTION * float(np.median(v))
    idx = np.flatnonzero(full)
    a, b = (int(idx[0]), int(idx[-1]) + 1) if len(idx) else (0, len(v))
    return {"accel": slice(seg.start, seg.start + a),
            "constant": slice(seg.start + a, seg.start + b),
            "decel": slice(seg.start + b, seg.stop)}
