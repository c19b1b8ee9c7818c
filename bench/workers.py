"""The one worker pool of the bench: every long job (HUMS sweep, RUL run, calibration and
campaign, the gap diagnosis and its blind benchmark) runs its independent pieces here.

`run_all(fn, jobs, ...)` is `[fn(job) for job in jobs]` over worker processes with a
progress bar (in this process with one worker or one job); `make_pool` gives the pool
itself to a caller that schedules its own work (the gap diagnosis starts its workers in
the background while it does the first, serial part).

Workers are spawned (not forked: numba and threads do not survive a fork well) with one
BLAS/OpenMP/numba thread each, so two workers use two cores and no more: the fitting
calls small dense linear algebra whose OpenBLAS threads would otherwise spin and take
the other core from the second worker (measured: a diagnosis took 2x longer with two
forked workers than alone).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures import TimeoutError as FuturesTimeout
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from tqdm import tqdm

from bench import BenchError

START_TIMEOUT_S = 120.0
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS")


def default_workers() -> int:
    """Two workers, or one on a one-core machine."""
    return max(1, min(2, os.cpu_count() or 1))


def run_all(fn: Callable[[Any], Any], jobs: Iterable[Any], workers: int | None = None,
            progress: bool = True, desc: str = "runs", unit: str = "run", *,
            initializer: Callable[..., Any] | None = None, initargs: tuple[Any, ...] = (),
            on_result: Callable[[Any], None] | None = None, leave: bool = False
            ) -> list[Any]:
    """[fn(job) for job in jobs], in job order, over `workers` processes, with a tqdm bar
    (`desc`, `unit`; kept on screen with `leave`). With ``workers=1`` or a single job
    everything runs in this process (tests, debugging, one-core machines).
    `initializer(*initargs)` runs once in each worker (once here when in-process);
    `on_result(result)` is called as each job finishes (in completion order)."""
    jobs = list(jobs)
    workers = default_workers() if workers is None else max(1, int(workers))
    bar = None
    if progress:
        bar = tqdm(total=len(jobs), desc=desc, unit=unit, leave=leave)
    results: list[Any] = [None] * len(jobs)

    def done(k: int, result: Any) -> None:
        results[k] = result
        if on_result is not None:
            on_result(result)
        if bar is not None:
            bar.update(1)

    try:
        if workers == 1 or len(jobs) <= 1:
            if initializer is not None:
                initializer(*initargs)
            for k, job in enumerate(jobs):
                done(k, fn(job))
            return results
        with make_pool(workers, initializer, initargs) as pool:
            futs = {pool.submit(fn, job): k for k, job in enumerate(jobs)}
            for f in as_completed(futs):
                try:
                    result = f.result()
                except BenchError:
                    raise
                except Exception as exc:  # noqa: BLE001 - worker crash, say which job
                    raise BenchError(f"{desc}: job {futs[f]} failed in a worker: "
                                     f"{type(exc).__name__}: {exc}") from exc
                done(futs[f], result)
        return results
    finally:
        if bar is not None:
            bar.close()


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
