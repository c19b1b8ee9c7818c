"""The one worker pool (`bench.workers.run_all`): job order, callbacks, initializer, errors,
in this process and over spawned workers."""

from __future__ import annotations

import pytest

from bench import BenchError
from bench.workers import run_all

_STATE: dict[str, str] = {}


def _square(x: int) -> int:
    return x * x


def _set(value: str) -> None:
    _STATE["value"] = value


def _read(x: int) -> tuple[str | None, int]:
    return _STATE.get("value"), x


def _fail_on_two(x: int) -> int:
    if x == 2:
        raise ValueError("boom")
    return x


def test_in_process_keeps_job_order_and_calls_back():
    seen: list[int] = []
    got = run_all(_square, range(5), workers=1, progress=False, on_result=seen.append)
    assert got == [0, 1, 4, 9, 16]
    assert seen == [0, 1, 4, 9, 16]
    assert run_all(_square, [], workers=2, progress=False) == []


def test_initializer_runs_here_and_in_each_worker():
    _STATE.clear()
    assert run_all(_read, [1, 2], workers=1, progress=False, initializer=_set,
                   initargs=("here",)) == [("here", 1), ("here", 2)]
    seen: list[tuple[str | None, int]] = []
    got = run_all(_read, [1, 2, 3], workers=2, progress=False, initializer=_set,
                  initargs=("worker",), on_result=seen.append)
    assert got == [("worker", 1), ("worker", 2), ("worker", 3)]
    assert sorted(seen) == got          # every result reported, in completion order


def test_a_failing_job_is_a_bench_error_that_names_it():
    with pytest.raises(BenchError, match="job 2 failed in a worker: ValueError: boom"):
        run_all(_fail_on_two, [0, 1, 2, 3], workers=2, progress=False, desc="t")
    with pytest.raises(ValueError, match="boom"):      # in-process: the error itself
        run_all(_fail_on_two, [0, 1, 2, 3], workers=1, progress=False)
