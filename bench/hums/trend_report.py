"""What `bench hums prognose` shows of a trend prognosis (`bench.hums.trend_prognosis`):
a line per actuator, the statements of one actuator, the JSON of every estimate and a
figure per actuator.

JSON (`write_json`, streamed: one actuator at a time, so 10^6 tests need no more memory
than one actuator's): ``{actuator: [estimate, ...]}``, one estimate per test, as the
calibrated path writes them (``t``, ``warning``, ``rul_p5``, ``rul_p50``, ``rul_p95``)
plus ``rul_p25``, ``rul_p75``, ``toe_p50`` (the day of the median failure), ``value``,
``level_p5/p50/p95`` (the filtered level, in the index's unit), ``detected``,
``rul_open`` (a percentile beyond the horizon, given as the horizon),
``z_alarm`` and ``exp_cross_t`` (the peers), ``noise``, ``date`` (when the file gives
dates), ``notes`` (what makes this band untrustworthy; empty when nothing does) and,
with ``healthy_level``, ``healthy_sd``, ``healthy_tests``, ``failure_level``,
``warning_level``, ``unit`` and ``index``, what it was made against. RULs are in the
file's time unit (days for dates); none before the detection (null).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import IO, Any

import numpy as np

from bench.hums.trend_prognosis import TrendResult

MAX_FIGURES = 100


def _day(res: TrendResult, key: str) -> str:
    v = res.events.get(key)
    return res.trend.date(v) if v is not None else "-"


def _num(v: float, f: str = "{:.1f}") -> str:
    if v is None or not math.isfinite(v):
        return "open" if v == math.inf else "-"
    return f.format(v)


def table(results: list[TrendResult], names: list[str] | None = None) -> str:
    """One line per actuator: its last estimate, the detection and the peers' days. The
    name column is as wide as the longest of `names` (default: the results'), never cut."""
    w = max([12] + [len(n) for n in (names if names is not None else
                                     [r.trend.actuator for r in results])])
    lines = [f"{'actuator':>{w}s} {'tests':>5s} {'healthy':>9s} {'level':>9s} "
             f"{'detected':>10s} {'RUL p5':>8s} {'p50':>8s} {'p95':>8s} {'warning':>7s} "
             f"{'z-score':>10s} {'exp. cross':>10s}"]
    for r in results:
        c = r.cols
        k = len(c["t"]) - 1
        h = f"{r.ref.level:.4g}" if r.ref else "-"
        warned = "yes" if np.any(c["warning"] > 0) else "no"
        cross = c["exp_cross_t"][k]
        p95 = (">" if c["rul_open"][k] else "") + _num(c["rul_p95"][k])
        lines.append(
            f"{r.trend.actuator:>{w}s} {k + 1:5d} {h:>9s} {_num(c['level_p50'][k], '{:.4g}'):>9s} "
            f"{_day(r, 'detected_t'):>10s} {_num(c['rul_p5'][k]):>8s} "
            f"{_num(c['rul_p50'][k]):>8s} {p95:>8s} {warned:>7s} "
            f"{_day(r, 'z_alarm_t'):>10s} "
            f"{(r.trend.date(cross) if math.isfinite(cross) else _num(cross)):>10s}")
    return "\n".join(lines)


def statements(r: TrendResult, time_unit: str = "days") -> list[str]:
    """What one actuator's prognosis says, in sentences: reference, threshold, detection,
    the last estimate and its notes, the peers."""
    tr, c, ev = r.trend, r.cols, r.events
    u = f" {r.unit}" if r.unit else ""
    k = len(c["t"]) - 1
    out = [f"{tr.actuator}: {tr.index}{(' [' + r.unit + ']') if r.unit else ''}, "
           f"{k + 1} tests, {tr.date(c['t'][0])} to {tr.date(c['t'][k])}"]
    out += [f"  {n}" for n in r.notes]
    if r.failure is not None:
        w = f", warning {r.warning_level:.4g}{u}" if r.warning_level is not None else ""
        out.append(f"  failure threshold {r.failure:.4g}{u}{w}")
    if "detected_t" in ev:
        out.append(f"  change from healthy detected on {_day(r, 'detected_t')} (began about "
                   f"{_day(r, 'change_t')})")
    if r.failure is not None and math.isfinite(c["rul_p50"][k]):
        out.append(f"  RUL as of {tr.date(c['t'][k])}: median {_num(c['rul_p50'][k])} "
                   f"{time_unit}, 90 % band {_num(c['rul_p5'][k])} to "
                   f"{'>' if c['rul_open'][k] else ''}{_num(c['rul_p95'][k])} {time_unit} "
                   "(failure about "
                   f"{tr.date(c['toe_p50'][k])})")
    out += [f"  note: {n}" for n in r.notes_at.get(k, []) if n not in r.notes]
    if "left_range_t" in ev:
        out.append(f"  the trend left the model's range on {_day(r, 'left_range_t')}")
    out.append(f"  peers on the same tests: z-score (3 sd of the healthy tests) alarm "
               f"{_day(r, 'z_alarm_t')}; exponential extrapolation " + (
                   f"crosses the threshold on {tr.date(c['exp_cross_t'][k])} (as of the "
                   "last test), " + (f"first within a test interval on "
                                     f"{_day(r, 'exp_alarm_t')}" if "exp_alarm_t" in ev
                                     else "never within a test interval")
                   if math.isfinite(c["exp_cross_t"][k]) else
                   "does not cross the threshold" if r.failure is not None else
                   "needs a threshold"))
    return out


def _constants(r: TrendResult) -> dict[str, Any]:
    ref = r.ref
    return {"index": r.trend.index, "unit": r.unit,
            "healthy_level": ref.level if ref else None,
            "healthy_sd": ref.sd if ref else None,
            "healthy_tests": ref.n if ref else None,
            "failure_level": r.failure, "warning_level": r.warning_level}


def write_actuator(fh: IO[str], r: TrendResult, first: bool) -> None:
    """One actuator's estimates into an open JSON object (`write_json`)."""
    const = _constants(r)
    fh.write(("" if first else ",\n") + json.dumps(r.trend.actuator) + ": [")
    for k in range(len(r.cols["t"])):
        e = r.estimate(k)
        e.update(const)
        fh.write(("" if k == 0 else ",\n ") + json.dumps(e, allow_nan=False))
    fh.write("]")


class StreamedJson:
    """The JSON of every estimate (module docstring), written actuator by actuator into a
    temporary file beside `path`, renamed to it when the block ends without an error (an
    interrupted run leaves no half file and no earlier file overwritten); ``-``: standard
    output, as it comes. No-op for None."""

    def __init__(self, path: str | Path | None) -> None:
        self.stdout = str(path) == "-"
        self.path = Path(path) if path and not self.stdout else None
        self.fh: IO[str] | None = None
        self.tmp = ""
        self.n = 0

    def __enter__(self) -> StreamedJson:
        if self.stdout:
            import sys
            self.fh = sys.stdout
            self.fh.write("{")
        elif self.path is not None:
            import os
            import tempfile
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, self.tmp = tempfile.mkstemp(dir=self.path.parent, prefix=".prognose-",
                                            suffix=".json")
            self.fh = os.fdopen(fd, "w")
            self.fh.write("{")
        return self

    def add(self, r: TrendResult) -> None:
        if self.fh is not None:
            write_actuator(self.fh, r, self.n == 0)
        self.n += 1

    def __exit__(self, exc_type: Any, *rest: Any) -> None:
        import os
        if self.stdout and self.fh is not None:
            self.fh.write("}\n" if exc_type is None else "\n")
            self.fh.flush()
            return
        if self.fh is None or self.path is None:
            return
        if exc_type is None:
            self.fh.write("}\n")
        self.fh.close()
        if exc_type is None:
            os.replace(self.tmp, self.path)
        else:
            os.unlink(self.tmp)


def write_json(results: list[TrendResult], path: str | Path) -> Path:
    """Every estimate of every actuator (module docstring)."""
    with StreamedJson(path) as out:
        for r in results:
            out.add(r)
    return Path(path)


def file_name(actuator: str, index: str) -> str:
    """A figure's file name from data: letters, digits and -_. kept, the rest '_', at
    most 80 characters, and a short hash of the exact names so distinct ones stay
    distinct."""
    raw = f"{actuator}\0{index}"
    keep = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in f"{actuator}_{index}")
    keep = keep.strip(".")[:80] or "trend"
    return f"{keep}-{hashlib.sha256(raw.encode()).hexdigest()[:8]}.png"


def figure(r: TrendResult, out_dir: str | Path, truth: float | None = None,
           time_unit: str = "days") -> Path:
    """The trend with its healthy band, thresholds and filtered level, and the RUL band
    over time (with the true RUL when `truth`, the day of failure, is given)."""
    # long: two panels, each a handful of plotting calls
    from matplotlib.figure import Figure
    tr, c, ev = r.trend, r.cols, r.events
    t = c["t"]
    fig = Figure(figsize=(9, 6.5))
    ax = fig.subplots(2, 1, sharex=True)
    ax[0].plot(t, c["value"], "k.", ms=3, label="tests")
    if r.ref is not None:
        ref = r.ref
        ax[0].axhspan(ref.level - 3 * ref.sd, ref.level + 3 * ref.sd, color="g", alpha=0.12,
                      label=f"healthy +-3 sd ({ref.n} tests)")
    ax[0].plot(t, c["level_p50"], "C0-", lw=1, label="filtered level")
    ax[0].fill_between(t, c["level_p5"], c["level_p95"], color="C0", alpha=0.25)
    if r.failure is not None:
        ax[0].axhline(r.failure, color="r", lw=1, label="failure threshold")
    if r.warning_level is not None:
        ax[0].axhline(r.warning_level, color="orange", lw=1, label="warning level")
    for key, col, lab in (("detected_t", "C2", "detection"), ("z_alarm_t", "m", "z-score peer"),
                          ("exp_alarm_t", "c", "exponential peer")):
        if key in ev:
            ax[0].axvline(ev[key], color=col, ls=":", lw=1.2, label=lab)
    ax[0].set(ylabel=f"{tr.index} [{r.unit}]" if r.unit else tr.index,
              title=f"{tr.actuator}: {tr.index}")
    ax[0].legend(fontsize=7, loc="upper left")
    top = np.nanmax(np.where(np.isfinite(c["rul_p50"]), c["rul_p50"], np.nan),
                    initial=1.0) * 2.0 if np.isfinite(c["rul_p50"]).any() else 1.0
    if truth is not None and math.isfinite(truth):
        top = max(top, 1.3 * (truth - t[0]))
        m = t <= truth
        ax[1].plot(t[m], truth - t[m], "r-", lw=1.2, label="true RUL")
    hi = np.minimum(np.nan_to_num(c["rul_p95"], nan=np.nan, posinf=10 * top), 10 * top)
    ax[1].fill_between(t, c["rul_p5"], hi, color="C0", alpha=0.2, label="RUL 5-95 %")
    ax[1].fill_between(t, c["rul_p25"], c["rul_p75"], color="C0", alpha=0.3, label="25-75 %")
    ax[1].plot(t, c["rul_p50"], "C0-", lw=1, label="median")
    cross = c["exp_cross_t"] - t
    ax[1].plot(t, np.where(np.isfinite(cross), cross, np.nan), "c--", lw=1,
               label="exponential peer")
    ax[1].set(ylim=(0, top), ylabel=f"RUL ({time_unit})",
              xlabel=f"time ({time_unit} since {tr.date(0.0)})" if tr.t0 is not None
              else f"time ({time_unit})")
    ax[1].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p = out / file_name(tr.actuator, tr.index)
    fig.savefig(p, dpi=80)
    return p
