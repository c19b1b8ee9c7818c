"""The Dask worker plugin that runs a job's `initializer(*initargs)` once in every worker
process of the job, including a worker that joins (or is restarted by its nanny) in the
middle of it. Its own module because it imports `distributed` (~0.5 s), which the
in-process path of `bench.runtime.workers.run_all` never needs."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin


class Initializer(WorkerPlugin):
    """`fn(*args)` in each worker, before the worker runs any of the job's tasks."""

    def __init__(self, fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
        self.fn = fn
        self.args = args

    def setup(self, worker: Any) -> None:
        self.fn(*self.args)
