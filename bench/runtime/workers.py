"""The one compute engine of the bench: every long job (HUMS sweep, RUL run, calibration
and campaign, the gap diagnosis and its blind benchmark, the fleet) runs its independent
pieces here, on Dask distributed (`bench.runtime.cluster`).

`run_all(fn, jobs, ...)` is `[fn(job) for job in jobs]` as Dask tasks with a progress bar:
on a LocalCluster of its own (127.0.0.1 only, `workers` single-threaded processes,
dashboard on a free local port) or on an existing cluster (`scheduler=ADDRESS`, or
``$BENCH_DASK_SCHEDULER``). With ``workers=1`` or a single job everything runs in this
process (tests, debugging, one-core machines). `make_pool` gives a started (or starting)
cluster to a caller that schedules its own work: the gap diagnosis starts its workers
in the background while it does the first, serial part.

Faults are Dask's: a task that raises is retried (`retries`, default 1) before its error
is reported; a worker process that dies costs only the tasks it was running, which the
scheduler runs again on another worker (up to ``distributed.scheduler.allowed-failures``
deaths per task), and the nanny starts a new worker. Results come back complete and in
job order. The tasks are the same functions on the same inputs as in-process, so the
results do not depend on the engine or on the number of workers.

On a cluster the progress bar is drawn from Dask's own diagnostics: `_DaskBar` is a
`distributed.diagnostics.progressbar.ProgressBar` (the scheduler's `Progress` plugin
reports the tasks left every 0.1 s, as `distributed.progress` does) that draws a tqdm bar
on stderr, in jobs (`chunk` per task), so it looks the same as the in-process bar, which
counts the jobs as they finish. Results are collected apart from the bar, with
`distributed.as_completed` (for `on_result`, and to name the job that failed). Dask's
live diagnostics are also on its dashboard, whose link is printed once on stderr when a
job with a progress bar starts a cluster.
"""

from __future__ import annotations

import re
import threading
import uuid
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from tqdm import tqdm

from bench import BenchError
from bench.runtime.cluster import Engine, check_address, default_workers, scheduler_address

RETRIES = 1
# Jobs carry their data (a study's cycles, a split's tables) in the task graph: a worker
# that dies then loses nothing, where data scattered to it would die with it. Dask warns
# from 10 MB ("Sending large graph ..., consider scatter"); the bench's own jobs stay
# quiet up to this size.
GRAPH_WARNING = "512MB"


class _Session:
    """One cluster shared by the `run_all` calls inside `session()` (started lazily)."""

    def __init__(self, workers: int | None, scheduler: str | None) -> None:
        self.workers = workers
        self.scheduler = scheduler_address(scheduler)
        self.engine: Engine | None = None

    def get(self, workers: int) -> Engine:
        if self.engine is None:
            self.engine = Engine(self.workers or workers, self.scheduler)
        return self.engine


_SESSIONS: list[_Session] = []


@contextmanager
def session(workers: int | None = None, scheduler: str | None = None) -> Iterator[None]:
    """Every `run_all` inside (that does not run in-process) shares one cluster, started
    at the first that needs it and stopped at the end: a command that calls `run_all`
    several times (calibration, then the campaign's runs) starts its workers once."""
    s = _Session(workers, scheduler)
    _SESSIONS.append(s)
    try:
        yield
    finally:
        _SESSIONS.remove(s)
        if s.engine is not None:
            s.engine.close()


def run_all(fn: Callable[[Any], Any], jobs: Iterable[Any], workers: int | None = None,
            progress: bool = True, desc: str = "runs", unit: str = "run", *,
            initializer: Callable[..., Any] | None = None, initargs: tuple[Any, ...] = (),
            on_result: Callable[[Any], None] | None = None, leave: bool = False,
            scheduler: str | None = None, retries: int = RETRIES,
            chunk: int = 1, label: Callable[[Any], str] | None = None) -> list[Any]:
    """[fn(job) for job in jobs], in job order, as Dask tasks on `workers` local
    processes (default: 2, or 1 on a one-core machine) or on the cluster of `scheduler`
    (an address, default ``$BENCH_DASK_SCHEDULER``; `workers` is then only the in-process
    switch), with a tqdm bar (`desc`, `unit`; kept on screen with `leave`).
    With ``workers=1`` or a single job everything runs in this process.
    `initializer(*initargs)` runs once in each worker (once here when in-process);
    `on_result(result)` is called as each job finishes (in completion order); a task that
    raises is retried `retries` times, then its error is a BenchError naming the job
    (`label(job)`, e.g. its file, else "job N").
    `chunk` > 1: on a cluster, each task runs that many consecutive jobs (jobs of ~0.1 s
    would otherwise pay Dask's per-task cost, a few ms of scheduler and transfer each);
    their results still come one by one (bar, `on_result`) as their task finishes, and a
    worker that dies costs the tasks it held (`chunk` jobs each), run again elsewhere."""
    jobs = list(jobs)
    addr = scheduler_address(scheduler)
    if addr is not None:          # refused even when the jobs run here (one job, 1 worker)
        check_address(addr)
    n = (default_workers() if addr is None else 2) if workers is None else int(workers)
    results: list[Any] = [None] * len(jobs)
    bar: Any = None

    def done(k: int, result: Any) -> None:
        results[k] = result
        if on_result is not None:
            on_result(result)
        if bar is not None and n_local:
            bar.update(1)

    def new_bar() -> Any:
        return tqdm(total=len(jobs), desc=desc, unit=unit, leave=leave) if progress else None

    n_local = n <= 1 or len(jobs) <= 1
    try:
        if n_local:
            bar = new_bar()
            if initializer is not None:
                initializer(*initargs)
            for k, job in enumerate(jobs):
                done(k, fn(job))
            return results
        shared = _SESSIONS[-1] if _SESSIONS and _SESSIONS[-1].scheduler == addr else None
        engine = shared.get(n) if shared is not None else Engine(n, addr)
        try:
            client = engine.client(announce=progress)   # the dashboard link before the bar
            bar = new_bar()
            _on_dask(client, fn, jobs, done, desc, retries,
                     None if initializer is None else (initializer, initargs),
                     own_cluster=engine.cluster is not None and shared is None,
                     chunk=chunk, bar=bar, label=label)
        finally:
            if shared is None:
                engine.close()
        return results
    finally:
        if bar is not None:
            bar.close()


def _on_dask(client: Any, fn: Callable[[Any], Any], jobs: list[Any],
             done: Callable[[int, Any], None], desc: str, retries: int,
             init: tuple[Callable[..., Any], tuple[Any, ...]] | None, own_cluster: bool,
             chunk: int = 1, bar: Any = None, label: Callable[[Any], str] | None = None
             ) -> None:
    """The jobs as tasks of `client`'s cluster (`chunk` consecutive jobs per task);
    `done(k, result)` as each one finishes; `bar` (tqdm) drawn by `_DaskBar`."""
    from distributed import as_completed
    name = f"{_slug(desc)}-{uuid.uuid4().hex[:8]}"
    plugin = None
    if init is not None:
        from bench.runtime.cluster_plugin import Initializer
        plugin = f"{name}-init"
        client.register_plugin(Initializer(*init), name=plugin)
    size = max(1, int(chunk))
    starts = list(range(0, len(jobs), size))
    import dask
    with dask.config.set({"distributed.admin.large-graph-warning-threshold": GRAPH_WARNING}):
        futs = client.map(_run_chunk, [fn] * len(starts), starts,
                          [jobs[k:k + size] for k in starts],
                          key=[f"{name}-{k}" for k in starts], retries=max(0, int(retries)))
    index = {f.key: i for i, f in enumerate(futs)}
    dbar = None if bar is None else _DaskBar(futs, client, bar, size, len(jobs))
    try:
        for f, result in as_completed(futs, loop=client.loop, with_results=True,
                                      raise_errors=False):
            i = index[f.key]
            try:
                if f.status != "finished":   # erred or cancelled: raise its error here
                    result = f.result()
            except BenchError:
                raise
            except Exception as exc:  # noqa: BLE001 - a task's error: say which job
                raise _job_error(exc, desc, jobs, label, starts[i], size) from exc
            futs[i] = None                 # the cluster may forget it now
            for j, r in enumerate(result):
                done(starts[i] + j, r)
        if dbar is not None:
            dbar.stopped.wait(5.0)         # its last report (all done) drawn
    finally:
        left = [f for f in futs if f is not None and not f.done()]
        if left:
            client.cancel(left)
        if plugin is not None and not own_cluster:
            try:                           # leave a shared cluster as it was
                client.unregister_worker_plugin(plugin)
            except Exception:  # noqa: BLE001 - best effort
                pass


def _job_error(exc: BaseException, desc: str, jobs: list[Any],
               label: Callable[[Any], str] | None, first: int, size: int) -> BenchError:
    """The BenchError of a task that failed: the job named by `label` (its file, say),
    else by its number; a task of `size` jobs from `first` that died as a whole names
    the first and says how many followed it."""
    def named(k: int) -> str:
        if label is not None:
            try:
                return str(label(jobs[k]))
            except Exception:  # noqa: BLE001 - a label that fails: the number
                pass
        return f"job {k}"
    if isinstance(exc, _JobFailed):
        return BenchError(f"{desc}: {named(exc.args[0])} failed in a worker: {exc.args[1]}")
    which = named(first) if size == 1 else f"{named(first)} (or one of the {size - 1} after it)"
    return BenchError(f"{desc}: {which} failed in a worker: {type(exc).__name__}: {exc}")


class _DaskBar:
    """A tqdm bar drawn from the scheduler's progress reports: Dask's `ProgressBar` (the
    diagnostics behind `distributed.progress`), listening on the client's event loop."""

    def __init__(self, futs: list[Any], client: Any, bar: Any, size: int, total: int
                 ) -> None:
        from distributed.diagnostics.progressbar import ProgressBar
        outer = self
        self.stopped = threading.Event()

        class _Bar(ProgressBar):  # type: ignore[misc]
            def _draw_bar(self, remaining: int, all: int, **kw: Any) -> None:  # noqa: A002
                done = total if remaining == 0 else min(total, (all - remaining) * size)
                if done > bar.n:
                    bar.update(done - bar.n)

            def _draw_stop(self, **kw: Any) -> None:
                outer.stopped.set()

        self.bar = _Bar(futs, scheduler=client.scheduler.address, interval="100ms")
        client.loop.add_callback(self._listen)

    async def _listen(self) -> None:
        try:
            await self.bar.listen()
        except Exception:  # noqa: BLE001 - a bar that cannot listen: results still come
            pass
        finally:
            self.stopped.set()


class _JobFailed(Exception):
    """A job of a chunk raised: args (job index, "ErrorType: message")."""


def _run_chunk(fn: Callable[[Any], Any], first: int, jobs: list[Any]) -> list[Any]:
    """A task: `fn` on `chunk` consecutive jobs (the first is job `first`), their results
    in order; a job's error names the job (`_JobFailed`)."""
    out = []
    for j, job in enumerate(jobs):
        try:
            out.append(fn(job))
        except BenchError:
            raise
        except Exception as exc:  # noqa: BLE001 - re-raised naming the job
            raise _JobFailed(first + j, f"{type(exc).__name__}: {exc}") from None
    return out


def _slug(desc: str) -> str:
    """A task-key prefix from a progress label ("hums sweep" -> "hums-sweep")."""
    return re.sub(r"[^A-Za-z0-9_.]+", "-", desc).strip("-") or "job"


class Pool:
    """A started (or starting) cluster for a caller that schedules its own tasks:
    `submit(fn, *args)` gives a Dask future (`.result()`); `shutdown()` stops it."""

    def __init__(self, workers: int, initializer: Callable[..., Any] | None = None,
                 initargs: tuple[Any, ...] = (), wait: bool = True,
                 scheduler: str | None = None, retries: int = RETRIES) -> None:
        self.engine = Engine(workers, scheduler, wait=False)
        self.init = None if initializer is None else (initializer, initargs)
        self.retries = retries
        self._client: Any = None
        self._plugin: str | None = None
        self._start_lock = threading.Lock()
        self._preloaded: threading.Event | None = None
        if wait:
            self.started()

    def started(self) -> Any:
        """The client, once the workers are up (BenchError when they cannot start)."""
        with self._start_lock:
            if self._client is None:
                client = self.engine.client()
                if self.init is not None:
                    from bench.runtime.cluster_plugin import Initializer
                    self._plugin = f"bench-init-{uuid.uuid4().hex[:8]}"
                    client.register_plugin(Initializer(*self.init), name=self._plugin)
                self._client = client
            return self._client

    def preload(self, fn: Callable[[], Any]) -> None:
        """Run `fn()` once on every worker as soon as the workers are up, in a background
        thread (imports and compiled code that the first task would otherwise load while
        the caller waits for it); best effort: where it fails, the first task pays."""
        done = self._preloaded = threading.Event()

        def run() -> None:
            try:
                self.started().run(fn)
            except Exception:  # noqa: BLE001 - best effort; submit() reports a real fault
                pass
            finally:
                done.set()
        threading.Thread(target=run, name="bench-dask-preload", daemon=True).start()

    def ready(self) -> bool:
        """Whether the workers are up (and through `preload`), without waiting: a caller
        with work it can do itself does it meanwhile instead of waiting in `started`."""
        if self._preloaded is not None:
            return self._preloaded.is_set()
        return self.engine.start_finished

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        return self.started().submit(fn, *args, pure=False, retries=self.retries)

    def share(self, obj: Any) -> Any:
        """`obj` sent once to every worker (a Dask future to pass to `submit` in its
        place): each worker then holds one copy for all the tasks that take it, instead
        of one pickled into every task."""
        return self.started().scatter(obj, broadcast=True, hash=False)

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        """Stop the cluster this pool started. With `wait` false, as in concurrent.futures,
        it returns at once and the cluster closes in a background thread (its workers'
        processes take about a second to stop; the caller has its results already); the
        thread is not a daemon, so the process's exit still waits for it.
        `cancel_futures` is accepted for concurrent.futures compatibility: pending tasks
        end with the client."""
        if self._plugin is not None and self.engine.cluster is None:
            try:                           # leave a shared cluster as it was
                self._client.unregister_worker_plugin(self._plugin)
            except Exception:  # noqa: BLE001 - best effort
                pass
        if wait:
            self.engine.close()
        else:
            threading.Thread(target=self.engine.close, name="bench-dask-close").start()

    def __enter__(self) -> Pool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()


def make_pool(workers: int, initializer: Callable[..., Any] | None = None,
              initargs: tuple[Any, ...] = (), wait: bool = True,
              scheduler: str | None = None) -> Pool:
    """A Dask cluster of `workers` single-threaded processes (or the one at `scheduler`).
    With `wait=False` it starts in the background (call `ensure_started` before relying
    on it)."""
    return Pool(workers, initializer, initargs, wait, scheduler)


def ensure_started(pool: Pool) -> None:
    """Wait for the workers; workers that cannot start (e.g. a script without a
    ``__main__`` guard) are a BenchError, not a hang."""
    pool.started()


__all__ = ["RETRIES", "Pool", "default_workers", "ensure_started", "make_pool", "run_all",
           "session"]
