"""The Dask engine of `bench.runtime.workers.run_all` on real LocalClusters (127.0.0.1): job
order, the initializer in every worker, retries, errors naming the job, and a worker
process killed mid-run costing only its tasks (results complete and equal to a serial
run). Bounded: small jobs, fixed inputs, the whole file in ~10-20 s."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from bench import BenchError
from bench.runtime.cluster import PRE_SPAWN_VARS, THREAD_VARS, Engine
from bench.runtime.workers import ensure_started, make_pool, run_all

_STATE: dict[str, str] = {}


def _set(value: str) -> None:
    _STATE["value"] = value


def _job(x: int) -> tuple[str | None, int]:
    """A short, deterministic job that needs the initializer's state."""
    time.sleep(0.2)
    return _STATE.get("value"), int(np.random.default_rng(x).integers(1_000_000))


def _counted(x: int) -> int:
    """`_job` that leaves a file per execution in the initializer's folder."""
    Path(_STATE["value"], f"{x}.{os.getpid()}.{time.monotonic_ns()}").touch()
    time.sleep(0.2)
    return int(np.random.default_rng(x).integers(1_000_000))


def _flaky(arg: tuple[str, int]) -> int:
    """Fails the first time it runs for `x` (marker file), succeeds the second."""
    folder, x = arg
    marker = Path(folder) / f"{x}.tried"
    if x % 2 and not marker.exists():
        marker.write_text("1")
        raise OSError(f"transient failure of job {x}")
    return x


def _fail_on_two(x: int) -> int:
    if x == 2:
        raise ValueError("boom")
    return x


@pytest.fixture(scope="module")
def engine():
    """One LocalCluster of 2 workers for the file (a start costs 2-15 s on the shared
    2-core VM): what run_all(workers=2) starts."""
    before = {k: os.environ.get(k) for k in PRE_SPAWN_VARS}
    with Engine(2) as e:
        e.client().wait_for_workers(2, timeout=60)
        # the nannies' pre-spawn variables do not stay in this process's environment
        assert {k: os.environ.get(k) for k in PRE_SPAWN_VARS} == before
        yield e


def test_cluster_order_initializer_retries_errors(engine, tmp_path, capfd):
    seen: list[tuple[str | None, int]] = []
    serial = run_all(_job, range(6), workers=1, progress=False, initializer=_set,
                     initargs=("worker",))
    addr = engine.cluster.scheduler_address
    assert addr.startswith("tcp://127.0.0.1:")
    envs = engine.client().run(_thread_env)        # one BLAS/OpenMP/numba thread each
    assert len(envs) == 2 and all(v == ["1"] * len(THREAD_VARS) for v in envs.values())
    got = run_all(_job, range(6), progress=True, initializer=_set,
                  initargs=("worker",), on_result=seen.append, desc="engine test",
                  scheduler=addr)
    assert got == serial and all(v == "worker" for v, _ in got)
    assert sorted(seen) == sorted(got)          # every result reported once
    err = capfd.readouterr().err
    assert err.count("dask dashboard: http://127.0.0.1:") == 1
    # the initializer's plugin is removed from a cluster the job did not start
    assert not engine.client().run_on_scheduler(_plugins)
    # a task that raises once is retried (retries=1 by default) ...
    assert run_all(_flaky, [(str(tmp_path), k) for k in range(4)], progress=False,
                   scheduler=addr) == [0, 1, 2, 3]
    assert len(list(tmp_path.glob("*.tried"))) == 2
    # ... one that keeps failing is a BenchError naming the job
    with pytest.raises(BenchError, match="job 2 failed in a worker: ValueError: boom"):
        run_all(_fail_on_two, [0, 1, 2, 3], progress=False, desc="t", retries=0,
                scheduler=addr)


def _thread_env() -> list[str | None]:
    return [os.environ.get(k) for k in THREAD_VARS]


def _plugins(dask_scheduler) -> list[str]:
    return [k for k in dask_scheduler.worker_plugins if "init" in k]


def _nbytes(b: bytes) -> int:
    return len(b)


def test_jobs_that_carry_their_data_raise_no_large_graph_warning(engine):
    """A study's jobs carry their cycles (16 MiB in all here): they travel in the graph,
    where a worker that dies loses nothing (scattered data would die with it), so Dask's
    "Sending large graph" warning (an error under this suite's filterwarnings) is not
    raised for them."""
    jobs = [bytes([k]) * (4 << 20) for k in range(4)]
    assert run_all(_nbytes, jobs, progress=False,
                   scheduler=engine.cluster.scheduler_address) == [4 << 20] * 4


def test_make_pool_submit_and_shutdown_on_a_cluster(engine):
    """The gap diagnosis' way: a pool started in the background, tasks submitted one by
    one, results read in submission order; shutting down leaves a shared cluster up."""
    pool = make_pool(2, _set, ("pool",), wait=False,
                     scheduler=engine.cluster.scheduler_address)
    ensure_started(pool)
    futs = [pool.submit(_job, k) for k in range(3)]
    got = [f.result() for f in futs]
    pool.shutdown(wait=False, cancel_futures=True)
    assert got == run_all(_job, range(3), workers=1, progress=False, initializer=_set,
                          initargs=("pool",))
    assert not engine.client().run_on_scheduler(_plugins)        # plugin removed
    assert len(engine.client().run(os.getpid)) == 2                # cluster still up


def test_a_worker_killed_mid_run_costs_only_its_tasks(engine, tmp_path):
    n = 16
    (tmp_path / "serial").mkdir()
    (tmp_path / "dask").mkdir()
    serial = run_all(_counted, range(n), workers=1, progress=False, initializer=_set,
                     initargs=(str(tmp_path / "serial"),))
    t0 = time.perf_counter()
    client = engine.client()
    client.wait_for_workers(2, timeout=60)
    pids = client.run(os.getpid)               # {worker address: pid}
    assert len(pids) == 2
    victim = sorted(pids.values())[0]
    killed: list[int] = []

    def kill_once(_result: object) -> None:
        if not killed:                          # after the first result: mid-run
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)

    got = run_all(_counted, range(n), progress=False, initializer=_set,
                  initargs=(str(tmp_path / "dask"),), on_result=kill_once,
                  scheduler=engine.cluster.scheduler_address)
    assert killed == [victim]
    assert got == serial                        # complete, in job order, same values
    runs = len(list((tmp_path / "dask").iterdir()))
    print(f"{runs} executions for {n} jobs")
    assert n <= runs <= n + 3                   # only the victim's tasks ran again
    after = _pids_without(client, victim)       # the nanny started a new worker
    assert victim not in after and len(after) == 2
    assert time.perf_counter() - t0 < 90


def _pids_without(client, victim: int, timeout: float = 60.0) -> set[int]:
    """The worker PIDs once the killed one is gone and its replacement is up."""
    t_end = time.monotonic() + timeout
    while True:
        try:
            pids = set(client.run(os.getpid, on_error="ignore").values())
        except Exception:  # noqa: BLE001 - the scheduler still lists the dead worker
            pids = set()
        if (victim not in pids and len(pids) == 2) or time.monotonic() > t_end:
            return pids
        time.sleep(0.2)


_NO_BOKEH = """
import sys
sys.modules["bokeh"] = None          # `import bokeh` fails in every process of the run
"""
_RUN = """
import sys
from bench.runtime.workers import run_all
if __name__ == "__main__":
    print(run_all(abs, [-1, -2, -3], workers=2, progress=True))
    print("bokeh" in sys.modules and sys.modules["bokeh"] is not None)
"""


def test_a_local_cluster_runs_without_bokeh(tmp_path):
    """bokeh is an extra (the dashboard): without it a job runs on two workers the same,
    and no dashboard link is printed (it would point at Dask's "needs bokeh" page)."""
    import subprocess
    import sys
    (tmp_path / "sitecustomize.py").write_text(_NO_BOKEH)      # the workers' too
    (tmp_path / "run.py").write_text(_RUN)
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(root)])}
    r = subprocess.run([sys.executable, str(tmp_path / "run.py")], capture_output=True,
                       text=True, timeout=180, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split("\n")[:2] == ["[1, 2, 3]", "False"]
    assert "dask dashboard" not in r.stderr


def test_a_local_cluster_leaves_nothing_in_the_temporary_folder(tmp_path):
    """The local cluster's lock files and worker folders go to a scratch folder of its
    own, removed when the job ends: Dask's default, a dask-scratch-space in the temporary
    folder, stayed behind after every run."""
    import subprocess
    import sys
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    (tmp_path / "run.py").write_text(
        "from bench.runtime.workers import run_all\n"
        "if __name__ == '__main__':\n"
        "    print(run_all(abs, [-1, -2, -3], workers=2, progress=False))\n")
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "TMPDIR": str(tmp), "PYTHONPATH": str(root)}
    r = subprocess.run([sys.executable, str(tmp_path / "run.py")], capture_output=True,
                       text=True, timeout=180, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split("\n")[0] == "[1, 2, 3]"
    assert sorted(p.name for p in tmp.iterdir()) == []
