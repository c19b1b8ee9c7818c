"""Worker processes for the long jobs (HUMS sweeps and campaigns, gap diagnosis).

Workers are spawned (not forked: numba and threads do not survive a fork well) with one
BLAS/OpenMP/numba thread each, so two workers use two cores and no more: the fitting
calls small dense linear algebra whose OpenBLAS threads would otherwise spin and take
the other core from the second worker (measured: a diagnosis took 2x longer with two
forked workers than alone).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FuturesTimeout
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from bench import BenchError

START_TIMEOUT_S = 120.0
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS")


def make_pool(workers: int, initializer: Callable[..., Any] | None = None,
              initargs: tuple[Any, ...] = (), wait: bool = True) -> ProcessPoolExecutor:
    """A pool of `workers` spawned single-threaded processes. With `wait=False` the
    workers start in the background (call `ensure_started` before relying on them)."""
    saved = {k: os.environ.get(k) for k in THREAD_VARS}
    for k in THREAD_VARS:
        os.environ[k] = "1"
    try:
        ctx = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                   initializer=initializer, initargs=initargs)
        # start the workers now, while the environment says one thread
        pool._bench_ready = [pool.submit(_noop) for _ in range(workers)]  # type: ignore
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    if wait:
        ensure_started(pool)
    return pool


def ensure_started(pool: ProcessPoolExecutor) -> None:
    """Wait for the workers; a worker that cannot start (e.g. a script without a
    ``__main__`` guard) is a BenchError, not a hang."""
    try:
        for f in getattr(pool, "_bench_ready", []):
            f.result(timeout=START_TIMEOUT_S)
    except (BrokenProcessPool, FuturesTimeout) as exc:
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.kill()
        raise BenchError(f"worker processes did not start ({type(exc).__name__}); a "
                         "script using bench.gap or bench.hums with workers > 1 needs an "
                         "`if __name__ == '__main__':` guard, or use workers=1") from None


def _noop() -> None:
    return None
