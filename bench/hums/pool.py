"""Run independent simulations on both cores with a progress bar.

Workers are spawned (not forked: numba and threads do not survive a fork well) with one
BLAS/OpenMP/numba thread each, so two workers use two cores and no more. With
``workers=1`` everything runs in this process (tests, debugging, one-core machines).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

from bench import BenchError

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS")


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
        saved = {k: os.environ.get(k) for k in THREAD_VARS}
        for k in THREAD_VARS:
            os.environ[k] = "1"
        try:
            ctx = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
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
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
        return results
    finally:
        if bar is not None:
            bar.close()
