"""Prognosis from external trends: a CSV of per-test health indexes over time,
from this bench or from a rig that is not this bench, into an RUL distribution per
actuator (`bench hums prognose --trends FILE.csv`).

CSV columns (a header row; any order; any cadence, e.g. one ground test a day):
``time`` (days, the unit of the calibration's time prior), ``actuator`` (any text),
``index`` (a name the calibration has a curve for; the campaign's: friction_current_a,
lost_motion_um, ci_harmonic) and ``value``. Optional usage rows: ``index`` = ``exposure`` with the
Archard exposure (N rev) used since the previous row of that actuator; with them the
prognosis uses usage and health (`WearPrognoser`), without them time is the exposure.
Unknown index names are listed and skipped; an actuator with none of the calibration's
indexes is an error.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums.prognosis import PrognosisCalibration, RulEstimate, WearPrognoser
from bench.hums.trend_io import EXPOSURE, Table, read_table

COLUMNS = ("time", "actuator", "index", "value")


def read_trends(path: str | Path) -> dict[str, dict[float, dict[str, float]]]:
    """actuator -> time -> {index: value}, read and checked by `bench.hums.trend_io`
    (one value of an index per time, finite values and times; dates become days since
    the first test); exposure rows under EXPOSURE."""
    return from_table(read_table(path))


def from_table(table: Table) -> dict[str, dict[float, dict[str, float]]]:
    """The calibrated path's view of a read trends table."""
    acc: dict[str, dict[float, dict[str, float]]] = defaultdict(lambda: defaultdict(dict))
    for tr in table.trends:
        for t, v in zip(tr.t.tolist(), tr.y.tolist(), strict=True):
            acc[tr.actuator][t][tr.index] = v
    for a, (ts, es) in table.exposure.items():
        for t, v in zip(ts.tolist(), es.tolist(), strict=True):
            acc[a][t][EXPOSURE] = v
    return {a: dict(sorted(ts.items())) for a, ts in acc.items()}


def prognose_series(series: dict[float, dict[str, float]], cal: PrognosisCalibration,
                    seed: int = 0, n_particles: int = 1000) -> list[RulEstimate]:
    """The prognosis of one actuator, one estimate per time of the series."""
    names = sorted({k for d in series.values() for k in d if k in cal.curves})
    if not names:
        known = sorted({k for d in series.values() for k in d})
        raise BenchError(f"no index the calibration knows ({', '.join(cal.curves)}); the "
                         f"trends have {', '.join(known)}")
    use_usage = any(EXPOSURE in d for d in series.values())
    pr = WearPrognoser(cal, names, n_particles=n_particles, seed=seed,
                       time_only=not use_usage)
    t0 = min(series)
    out = []
    for t, d in series.items():
        obs = {k: v for k, v in d.items() if k in cal.curves}
        out.append(pr.update(t - t0, d.get(EXPOSURE, 0.0), obs))
    return out


def _series_job(job: tuple[dict[float, dict[str, float]], dict[str, Any], int]
                ) -> list[RulEstimate]:
    ts, cal_json, seed = job
    return prognose_series(ts, PrognosisCalibration.from_json(cal_json), seed)


def prognose_trends(path: str | Path | Table, cal: PrognosisCalibration, seed: int = 0,
                    workers: int | None = 1, progress: bool = False
                    ) -> tuple[dict[str, list[RulEstimate]], list[str]]:
    """Every actuator of a trends CSV (or a read table): its estimates, and the index
    names skipped. `workers`: `bench.runtime.workers.run_all`'s (None: in this process below
    2,000 ground tests, else its default; each actuator's filter has its own seed, so
    the numbers do not depend on it); `progress`: a tqdm bar in actuators."""
    from tqdm import tqdm

    from bench.runtime.workers import run_all
    data = from_table(path) if isinstance(path, Table) else read_trends(path)
    skipped = sorted({k for ts in data.values() for d in ts.values() for k in d
                      if k not in cal.curves and k != EXPOSURE})
    if workers is None and sum(len(ts) for ts in data.values()) < 2000:
        workers = 1
    bar = tqdm(total=len(data), unit="actuator", desc="prognosis", disable=not progress,
               leave=False, delay=1.0)
    try:
        got = run_all(_series_job, [(ts, cal.to_json(), seed) for ts in data.values()],
                      workers, progress=False, on_result=lambda _r: bar.update(1))
    finally:
        bar.close()
    return dict(zip(data, got, strict=True)), skipped


def outside_calibration(tab: Table, cal: PrognosisCalibration) -> list[str]:
    """A note per index with values beyond its calibrated curve (by more than 3 noise
    sd): their wear is read at the curve's end, the band cannot be trusted there."""
    out = []
    for name in sorted({tr.index for tr in tab.trends if tr.index in cal.curves}):
        c = cal.curves[name]
        lo = min(c) - 3 * cal.sigma.get(name, 0.0)
        hi = max(c) + 3 * cal.sigma.get(name, 0.0)
        bad = [(tr.actuator, float(tr.t[k]), float(tr.y[k])) for tr in tab.trends
               if tr.index == name for k in np.flatnonzero((tr.y < lo) | (tr.y > hi))]
        if bad:
            a, t, v = bad[0]
            out.append(f"{len(bad)} value(s) of {name} outside the calibrated range "
                       f"{lo:.4g} to {hi:.4g} (first: actuator {a} at {t:g}, {v:.4g}): "
                       "their wear is read at the curve's end, the band is not to be "
                       "trusted there")
    return out


def table(results: dict[str, list[RulEstimate]], t0: dict[str, float] | None = None) -> str:
    """One line per actuator: last time, wear, RUL percentiles, warning."""
    lines = [f"{'actuator':>12s} {'tests':>5s} {'w p50':>6s} {'RUL p5':>8s} {'p25':>8s} "
             f"{'p50':>8s} {'p75':>8s} {'p95':>8s}  warning"]
    for a, ests in results.items():
        e = ests[-1]
        r = e.rul_pct
        lines.append(f"{a:>12s} {len(ests):5d} {e.w_pct['50']:6.3f} {r['5']:8.1f} "
                     f"{r['25']:8.1f} {r['50']:8.1f} {r['75']:8.1f} {r['95']:8.1f}  "
                     + ("yes" if any(x.warning for x in ests) else "no"))
    return "\n".join(lines)


def to_json(results: dict[str, list[RulEstimate]]) -> dict[str, Any]:
    def clean(v: float) -> float | None:
        return v if math.isfinite(v) else None
    return {a: [{k: clean(v) for k, v in e.row().items()} for e in ests]
            for a, ests in results.items()}


def default_calibration_path() -> Path:
    """Where `bench hums campaign --usage` leaves its calibration for `prognose`."""
    import os
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "ema-hums-bench" / "prognosis-calibration.json"


def load_calibration(path: str | Path | None) -> PrognosisCalibration:
    """A prognosis calibration JSON (`path`, else the cache's)."""
    import json
    p = Path(path) if path else default_calibration_path()
    if not p.is_file():
        raise BenchError(f"no prognosis calibration at {p}: run `bench hums campaign "
                         "--usage` first, or pass --calibration FILE.json")
    try:
        return PrognosisCalibration.from_json(json.loads(p.read_text()))
    except BenchError as exc:
        raise BenchError(f"{p}: {exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise BenchError(f"{p}: not JSON ({exc})") from None
    except RecursionError:
        raise BenchError(f"{p}: not a prognosis calibration (nested too deep to read)"
                         ) from None
