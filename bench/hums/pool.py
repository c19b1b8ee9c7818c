"""Run independent simulations on both cores with a progress bar.

Workers come from `bench.workers.make_pool` (spawned, one BLAS/OpenMP/numba thread
each). With ``workers=1`` everything runs in this process (tests, debugging, one-core
machines).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import as_completed
from typing import Any

from bench import BenchError
from bench.workers import make_pool


def default_workers() -> int:
    return max(1, min(2, os.cpu_count() or 1))


def run_all(fn: Callable[[Any], Any], jobs: Iterable[Any], workers: int | None = None,
            progress: bool = True, desc: str = "runs", unit: str = "run") -> list[Any]:
    """[fn(job) for job in jobs], in job order, over `workers` processes, with tqdm."""
    jobs = list(jobs)
    workers = default_workers() if workers is None else max(1, int(workers))
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), desc=desc, unit=unit, leave=False)
    results: list[Any] = [None] * len(jobs)
    try:
        if workers == 1 or len(jobs) <= 1:
            for k, job in enumerate(jobs):
                results[k] = fn(job)
                if bar is not None:
                    bar.update(1)
            return results
        pool = make_pool(workers)
        with pool:
            futs = {pool.submit(fn, job): k for k, job in enumerate(jobs)}
            for f in as_completed(futs):
                try:
                    results[futs[f]] = f.result()
                except BenchError:
                    raise
                except Exception as exc:  # noqa: BLE001 - worker crash, say which job
                    raise BenchError(f"{desc}: job {futs[f]} failed in a worker: "
                                     f"{type(exc).__name__}: {exc}") from exc
                if bar is not None:
                    bar.update(1)
        return results
    finally:
        if bar is not None:
            bar.close()
