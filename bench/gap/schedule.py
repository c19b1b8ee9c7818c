"""Where a diagnosis's candidate fits run when it has worker processes (`bench.gap.
diagnose`, `Options.workers` > 1): the same function on the same problem everywhere, so
the results do not depend on where a fit ran; only the order and the place change.

- The workers start in the background (`bench.runtime.workers.Pool`) and load the
  fit's modules and compiled loops as soon as they are up (`warm_worker`, `Pool.preload`).
  Until they are, this process fits the cheapest candidates itself, with single-threaded
  BLAS as in a worker (`here`).
- The problem goes to each worker once (`Pool.share`), not pickled into every task: a
  worker keeps one copy for all its tasks, with its cache of re-simulations
  (`bench.gap.problem.Problem._loop_cols`).
- The costliest fits are submitted first (`weight`), so that no worker is left with a
  long fit at the end while the other idles.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from typing import Any

from bench.gap import effects as E
from bench.gap import resim as R
from bench.gap.problem import Problem
from bench.runtime.workers import ensure_started

TASK_MODULE = "bench.gap.diagnose"     # where the task function lives (`on_pool`'s `task`)


def warm_worker() -> None:
    """What a worker process loads before its first fit: the task's module and the
    compiled closed loops (`resim.warm`)."""
    importlib.import_module(TASK_MODULE)
    R.warm()


def weight(names: Sequence[str], p: Problem) -> int:
    """A rank of a task's cost for scheduling: the parameters its closed-loop effects fit
    (an effect on the log alone re-uses the nominal re-simulation and costs next to
    nothing)."""
    effs = [E.get(n) for n in names]
    return sum(len(e.params) for e in effs if not e.in_log(p.base)) * 8 + len(effs)


def shared(pool: Any, p: Problem, h: Problem | None, strip: Callable[[Problem], Problem]
           ) -> tuple[Any, Any]:
    """The problems as the workers get them (`strip`ped), sent once per diagnosis
    (`Pool.share`) and kept on the pool for its later tasks; pickled into each task where
    the pool cannot share (e.g. a `concurrent.futures` executor)."""
    memo = getattr(pool, "_gap_shared", None)
    if memo is not None and memo[0] is p and memo[1] is h:
        return memo[2], memo[3]
    ps, hs = strip(p), (strip(h) if h is not None else None)
    share = getattr(pool, "share", None)
    if share is not None:
        ps = share(ps)
        hs = share(hs) if hs is not None else None
    try:
        pool._gap_shared = (p, h, ps, hs)
    except AttributeError:
        pass
    return ps, hs


def here(evaluate: Callable[..., Any], *args: Any) -> Any:
    """`evaluate(*args)` in this process as a worker process runs it: with single-threaded
    BLAS (the workers' `bench.runtime.cluster.THREAD_VARS`), whose sums are not split
    across threads, so that a fit does not depend on the process that ran it."""
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1):
        return evaluate(*args)


def on_pool(task: Callable[..., Any], evaluate: Callable[..., Any],
            strip: Callable[[Problem], Problem], tasks: Sequence[tuple[Any, Any]], p: Problem,
            h: Problem | None, pool: Any, bar: Any = None) -> list[Any]:
    """`evaluate(p, h, *t)` for every t of `tasks`, in task order: `task` (a module-level
    function of the same arguments) on the workers of `pool`, the costliest first; while
    the workers are not ready, the cheapest here (`here`)."""
    order = sorted(range(len(tasks)), key=lambda i: -weight(tasks[i][0], p))
    done: dict[int, Any] = {}
    ready = getattr(pool, "ready", None)
    while order and ready is not None and not ready():
        i = order.pop()
        done[i] = here(evaluate, p, h, *tasks[i])
    futs = {}
    if order:
        ensure_started(pool)
        ps, hs = shared(pool, p, h, strip)
        futs = {i: pool.submit(task, ps, hs, *tasks[i]) for i in order}
    out = []
    for i in range(len(tasks)):
        out.append(done[i] if i in done else futs[i].result())
        if bar is not None:
            bar.update(1)
    return out
