"""The compute engine (`bench.runtime.workers.run_all`) in this process: job order, callbacks,
initializer, errors, and when it stays in-process (no cluster: workers=1, one job, even
with a scheduler configured). The Dask cluster itself: tests/integration/test_workers_dask.py."""

from __future__ import annotations

import pytest

from bench.runtime.cluster import ENV_SCHEDULER, default_workers, scheduler_address
from bench.runtime.workers import _slug, run_all

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
    assert run_all(_square, [7], workers=2, progress=False) == [49]   # one job: here


def test_initializer_runs_here_in_process():
    _STATE.clear()
    assert run_all(_read, [1, 2], workers=1, progress=False, initializer=_set,
                   initargs=("here",)) == [("here", 1), ("here", 2)]


def test_in_process_error_is_the_error_itself():
    with pytest.raises(ValueError, match="boom"):
        run_all(_fail_on_two, [0, 1, 2, 3], workers=1, progress=False)


def test_scheduler_address_from_argument_or_environment(monkeypatch):
    monkeypatch.delenv(ENV_SCHEDULER, raising=False)
    assert scheduler_address(None) is None
    assert scheduler_address("tcp://127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    monkeypatch.setenv(ENV_SCHEDULER, " tcp://127.0.0.1:9999 ")
    assert scheduler_address(None) == "tcp://127.0.0.1:9999"
    assert scheduler_address("tcp://127.0.0.1:1") == "tcp://127.0.0.1:1"   # flag wins
    # workers=1 stays in this process: the (unreachable) scheduler is never contacted
    assert run_all(_square, [1, 2, 3], workers=1, progress=False) == [1, 4, 9]
    assert 1 <= default_workers() <= 2


def test_task_keys_are_readable_on_the_dashboard():
    assert _slug("hums sweep") == "hums-sweep"
    assert _slug("gap-bench") == "gap-bench"
    assert _slug("  ") == "job"


def test_session_starts_nothing_for_in_process_jobs():
    from bench.runtime.workers import _SESSIONS, session
    with session(2):
        assert run_all(_square, [3], workers=2, progress=False) == [9]
        assert _SESSIONS[-1].engine is None         # one job: no cluster was started
    assert not _SESSIONS


@pytest.mark.parametrize("argv", [["hums", "sweep"], ["hums", "rul"], ["hums", "campaign"],
                                  ["gap", "x.log"], ["gap-bench"],
                                  ["rig", "study", "d", "--calibrate-runs", "1",
                                   "--holdout-runs", "2", "-o", "o"]])
def test_every_command_with_workers_takes_a_scheduler(argv):
    from bench.cli import build_parser
    full = [*argv, "--workers", "3", "--scheduler", "tcp://127.0.0.1:8786"]
    args = build_parser(full).parse_args(full)
    assert args.workers == 3 and args.scheduler == "tcp://127.0.0.1:8786"
    assert build_parser(argv).parse_args(argv).scheduler is None


def test_the_usage_campaign_runs_on_the_given_scheduler(monkeypatch):
    """`bench hums campaign --usage --scheduler ADDR` took the flag and ignored it (its
    run_all calls started a local cluster): its work now runs inside the command's
    session, as the other campaign does."""
    from bench import BenchError
    from bench.cli import main
    from bench.hums import prognosis_campaign as PC
    from bench.runtime import cluster as C
    from bench.runtime import workers as W
    seen = []
    monkeypatch.setattr(C, "probe_scheduler", lambda *a, **k: None)   # no scheduler here

    def fake(*a, **kw):
        seen.append([s.scheduler for s in W._SESSIONS])
        raise BenchError("stop here")
    monkeypatch.setattr(PC, "run_usage_campaign", fake)
    assert main(["hums", "campaign", "--usage", "--runs", "2",
                 "--scheduler", "tcp://127.0.0.1:8786"]) != 0
    assert seen == [["tcp://127.0.0.1:8786"]]


@pytest.mark.parametrize("address", ["bogus", "tcp://host:abc", "foo://host:1"])
def test_a_scheduler_address_that_is_not_one_is_refused_at_once(monkeypatch, address):
    """Found by fuzzing: `--scheduler bogus` printed the error, then the
    half-made distributed Client hung the interpreter's exit for 40 s and printed a
    TimeoutError traceback from its __del__."""
    import time

    from bench import BenchError
    from bench.runtime.cluster import Engine
    t0 = time.monotonic()
    with pytest.raises(BenchError, match=f"not a Dask scheduler address: '{address}'"):
        Engine(2, address)
    monkeypatch.setenv(ENV_SCHEDULER, address)
    with pytest.raises(BenchError, match=r"\$BENCH_DASK_SCHEDULER\) as tcp://HOST:PORT"):
        Engine(2)
    assert time.monotonic() - t0 < 5.0


def test_a_bad_scheduler_address_is_refused_when_the_jobs_would_run_here(monkeypatch):
    """`--scheduler bogus` with one job (or one worker) ran the job in-process and exited
    0: the address was never looked at (found by fuzzing)."""
    from bench import BenchError
    from bench.runtime.workers import run_all
    with pytest.raises(BenchError, match="not a Dask scheduler address: 'bogus'"):
        run_all(abs, [-1], workers=1, scheduler="bogus")
    monkeypatch.setenv(ENV_SCHEDULER, "tcp://h:abc")
    with pytest.raises(BenchError, match="not a Dask scheduler address"):
        run_all(abs, [-1, -2], workers=1)
    monkeypatch.delenv(ENV_SCHEDULER)
    assert run_all(abs, [-1, -2], workers=1) == [1, 2]
