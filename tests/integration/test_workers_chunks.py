"""`bench.runtime.workers.run_all(chunk=N)` on a real LocalCluster (127.0.0.1): several jobs per
Dask task (the fleet's short logs), results still in job order and reported one by one,
a failing job named by its own index, and a worker killed mid-run costing only the
chunks it held."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pytest

from bench import BenchError
from bench.fleet.ingest import CHUNK_LOGS, chunk_size
from bench.runtime.cluster import Engine
from bench.runtime.workers import run_all

_DIR: dict[str, str] = {}


def _set(folder: str) -> None:
    _DIR["folder"] = folder


def _square(x: int) -> int:
    """A short job leaving a file per execution in the initializer's folder."""
    Path(_DIR["folder"], f"{x}.{os.getpid()}.{time.monotonic_ns()}").touch()
    time.sleep(0.05)
    return x * x


def _fail_on_five(x: int) -> int:
    if x == 5:
        raise ValueError("boom")
    return x


def test_chunk_size_keeps_tasks_short_and_workers_busy():
    assert chunk_size(10_000, 2) == CHUNK_LOGS
    assert chunk_size(120, 2) == 8           # at least 8 tasks per worker
    assert chunk_size(3, 2) == 1


class _Bar:
    """A tqdm stand-in recording what drew it."""
    made: list[_Bar] = []

    def __init__(self, total: int, **kw: object) -> None:
        self.total, self.n, self.threads = total, 0, set()
        _Bar.made.append(self)

    def update(self, k: int) -> None:
        self.n += k
        self.threads.add(threading.current_thread().name)

    def close(self) -> None:
        pass


def test_chunks_keep_order_report_each_job_and_survive_a_killed_worker(tmp_path,
                                                                        monkeypatch):
    n, chunk = 40, 4
    with Engine(2) as engine:
        client = engine.client()
        client.wait_for_workers(2, timeout=60)
        addr = engine.cluster.scheduler_address
        seen: list[int] = []
        (tmp_path / "a").mkdir()
        got = run_all(_square, range(n), progress=False, initializer=_set,
                      initargs=(str(tmp_path / "a"),), on_result=seen.append,
                      scheduler=addr, chunk=chunk)
        assert got == [x * x for x in range(n)] and sorted(seen) == got
        # the bar is drawn from the scheduler's progress reports (Dask's ProgressBar on
        # the client's event loop), not by the loop that collects the results
        monkeypatch.setattr("bench.runtime.workers.tqdm", _Bar)
        got = run_all(_square, range(10), progress=True, initializer=_set,
                      initargs=(str(tmp_path / "a"),), scheduler=addr, chunk=3)
        bar = _Bar.made[-1]
        assert got == [x * x for x in range(10)]
        assert bar.total == 10 and bar.n == 10
        assert threading.current_thread().name not in bar.threads, bar.threads
        monkeypatch.undo()
        with pytest.raises(BenchError, match="job 5 failed in a worker: ValueError: boom"):
            run_all(_fail_on_five, range(12), progress=False, retries=0, scheduler=addr,
                    chunk=4)
        with pytest.raises(BenchError, match="log5.log failed in a worker: ValueError: boom"):
            run_all(_fail_on_five, range(12), progress=False, retries=0, scheduler=addr,
                    chunk=4, label=lambda job: f"log{job}.log")
        victim = sorted(client.run(os.getpid).values())[0]
        killed: list[int] = []

        def kill_once(_result: object) -> None:
            if not killed:
                os.kill(victim, signal.SIGKILL)
                killed.append(victim)

        (tmp_path / "b").mkdir()
        got = run_all(_square, range(n), progress=False, initializer=_set,
                      initargs=(str(tmp_path / "b"),), on_result=kill_once,
                      scheduler=addr, chunk=chunk)
        assert killed == [victim]
        assert got == [x * x for x in range(n)]
        runs = len(list((tmp_path / "b").iterdir()))
        assert n <= runs <= n + 2 * chunk      # only the victim's chunk(s) ran again
