"""`bench hums prognose` on a rig's own trends: which trends, which path, and the run
over every actuator with a progress bar.

`choose_path` decides between the campaign's calibrated prognosis (`prognosis_trends`)
and the trend's own (`trend_prognosis`): the calibrated one when the trends' index names
are curves of the calibration (the one given, else the cache's) and no option of the
trend's own path is given; the trend's own otherwise, with a note saying why.

`run` prognoses the actuators in chunks of `CHUNK` (each chunk's results are handed to
`on_result` and dropped, so memory stays that of one chunk whatever the number of
tests), in this process (the default: ~1 ms of CPU per test, less than what starting
Dask workers costs below ~10^5 tests) or on `--workers` Dask workers
(`bench.runtime.workers.run_all`), with one tqdm bar in tests.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.hums.trend_io import Table, Trend
from bench.hums.trend_prognosis import Settings, TrendResult, prognose

CHUNK = 2000              # actuators per chunk held in memory at once
TREND_OPTIONS = ("failure", "warning", "healthy_tests", "unit", "decreasing", "index", "truth",
                 "figures")


def select(table: Table, index: str | None) -> list[Trend]:
    """The trends of the index the user names (or the file's only one)."""
    names = table.indexes()
    if index is None:
        if len(names) > 1:
            raise BenchError(f"{table.path}: the trends have {len(names)} indexes ("
                             + ", ".join(names[:8]) + ("..." if len(names) > 8 else "")
                             + "): choose one with --index")
        index = names[0]
    elif index not in names:
        raise BenchError(f"{table.path}: no index {index!r} (the file has "
                         + ", ".join(names[:8]) + ")")
    return [tr for tr in table.trends if tr.index == index]


def choose_path(args: Any, table: Table) -> tuple[str, Any, str | None]:
    """("calibration", the calibration, note) or ("trend", None, note) (module
    docstring). `args`: the CLI's options."""
    from bench.hums.prognosis_trends import default_calibration_path, load_calibration
    given = [o for o in TREND_OPTIONS if getattr(args, o, None) not in (None, False)]
    if getattr(args, "time_unit", "days") != "days":
        given.append("time_unit")
    if args.model == "calibration" and given:
        raise BenchError("--model calibration takes none of --"
                         + ", --".join(g.replace("_", "-") for g in given))
    if args.model == "trend" or (given and args.model == "auto"):
        return "trend", None, None
    path = Path(args.calibration) if args.calibration else default_calibration_path()
    if not path.is_file():
        if args.model == "calibration" or args.calibration:
            load_calibration(args.calibration)          # its one-line error
        return "trend", None, ("no prognosis calibration (bench hums campaign --usage): "
                               "the trend's own prognosis")
    cal = load_calibration(str(path))
    known = [n for n in table.indexes() if n in cal.curves]
    if known:
        return "calibration", cal, None
    if args.model == "calibration":
        raise BenchError(f"no index the calibration knows ({', '.join(cal.curves)}); the "
                         f"trends have {', '.join(table.indexes()[:8])}")
    return "trend", None, (f"the calibration {path} has no curve for "
                           f"{', '.join(table.indexes()[:3])}: the trend's own prognosis")


def _job(job: tuple[Trend, Settings]) -> TrendResult:
    return prognose(*job)


def run(trends: list[Trend], settings: Settings, on_result: Callable[[TrendResult], None],
        workers: int | None = None, progress: bool = True) -> None:
    """Every trend's prognosis, handed to `on_result` in file order (module docstring)."""
    from tqdm import tqdm

    from bench.runtime.workers import run_all, session
    total = sum(len(tr.t) for tr in trends)
    n = 1 if workers is None else workers
    bar = tqdm(total=total, unit="test", desc="prognosis", disable=not progress,
               leave=False, delay=1.0)

    def done(r: TrendResult) -> None:
        bar.update(len(r.cols["t"]))
    try:
        with session(n):
            for chunk in _chunks(trends, CHUNK):
                for r in run_all(_job, [(tr, settings) for tr in chunk], n, progress=False,
                                 on_result=done, chunk=max(1, len(chunk) // 40)):
                    on_result(r)
    finally:
        bar.close()


def _chunks(items: list[Trend], size: int) -> Iterable[list[Trend]]:
    for k in range(0, len(items), size):
        yield items[k:k + size]
