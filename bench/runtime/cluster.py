"""The bench's connection to Dask distributed: a `distributed.Client` on a LocalCluster of
its own (this machine, 127.0.0.1 only) or on an existing scheduler (`--scheduler ADDRESS`
or ``$BENCH_DASK_SCHEDULER``). `bench.runtime.workers` runs the jobs on it.

The local cluster has one worker process per core (at most `workers`), one thread each,
and one BLAS/OpenMP/numba thread per worker, so two workers use two cores and no more:
the fitting calls small dense linear algebra whose OpenBLAS threads would otherwise spin
and take the other core from the second worker (measured with the old pool: a diagnosis
took 2x longer with two multi-threaded workers than alone). Dask sets OMP, MKL and
OpenBLAS to one thread before it spawns a worker (``distributed.nanny.pre-spawn-environ``);
numba's thread count is set here (the nanny's ``env``, before any bench module is
imported in the worker). An existing cluster is the operator's: start its workers with
``--nthreads 1`` and the same variables (docs/performance.md, "Running on a cluster").

Workers are spawned processes (Dask's default; numba and threads do not survive a fork
well), so a script that starts a cluster needs an ``if __name__ == '__main__':`` guard.
"""

from __future__ import annotations

import logging
import os
import shutil
import sys
import tempfile
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from bench import BenchError

ENV_SCHEDULER = "BENCH_DASK_SCHEDULER"
START_TIMEOUT_S = 120.0           # a local cluster's workers (spawn, imports)
CONNECT_TIMEOUT_S = 20.0          # an existing scheduler
CLOSE_TIMEOUT_S = 30.0
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS")
PRE_SPAWN_VARS = (*THREAD_VARS, "MALLOC_TRIM_THRESHOLD_", "PYTHONHASHSEED")
DASHBOARD = "127.0.0.1:0"          # a free port on the loopback interface

SCHEDULER_HELP = ("run on the existing Dask cluster of this scheduler (e.g. "
                  "tcp://127.0.0.1:8786; default: $BENCH_DASK_SCHEDULER, else a local "
                  "cluster of --workers processes on 127.0.0.1)")

_shown: set[str] = set()           # dashboard links already printed by this process


@contextmanager
def environ_kept(keys: Iterable[str]) -> Iterator[None]:
    """This process's environment variables `keys` put back as they were on leaving (set
    again, or removed where they were not set)."""
    saved = {k: os.environ.get(k) for k in keys}
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def dashboard_available() -> bool:
    """Whether a local cluster can serve Dask's dashboard: it needs bokeh (the
    ``dashboard`` extra); without it the cluster runs the same, with no dashboard."""
    import importlib.util
    return importlib.util.find_spec("bokeh") is not None


def scheduler_address(scheduler: str | None = None) -> str | None:
    """The scheduler to use: `scheduler`, else ``$BENCH_DASK_SCHEDULER``, else None (a
    local cluster)."""
    addr = scheduler or os.environ.get(ENV_SCHEDULER, "").strip()
    return addr or None


def check_address(address: str) -> None:
    """BenchError unless `address` reads as a Dask scheduler address (a distributed
    Client given one that does not, such as "bogus", raised, then hung the interpreter's
    exit for 40 s in its __del__ and printed a traceback)."""
    from distributed.comm.addressing import get_address_host_port, parse_address
    try:
        scheme, _ = parse_address(address)
        if scheme not in ("inproc", "ucx"):         # no host:port to check
            get_address_host_port(address)
    except ValueError as exc:
        raise BenchError(f"not a Dask scheduler address: {address!r} ({exc}); give "
                         "--scheduler (or $BENCH_DASK_SCHEDULER) as tcp://HOST:PORT"
                         ) from None


PROBE_TIMEOUT_S = 5.0
"""How long a scheduler has to accept a connection and send its handshake."""
MAX_HANDSHAKE_BYTES = 1 << 26


def probe_scheduler(address: str, timeout: float = PROBE_TIMEOUT_S) -> None:
    """BenchError in one line, within `timeout`, unless a Dask scheduler answers at the
    tcp:// `address`: it accepts the connection and sends its handshake at once (a
    distributed comm's first frame: an 8-byte length). Something else listening there
    (an HTTP server) sends nothing, and a distributed Client would wait out its whole
    connect timeout and say only "timed out". Other schemes are left to the Client."""
    import socket

    from distributed.comm.addressing import get_address_host_port, parse_address
    check_address(address)
    scheme, _ = parse_address(address)
    if scheme != "tcp":
        return
    host, port = get_address_host_port(address)
    what = f"the Dask scheduler {address}"
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as exc:
        raise BenchError(f"cannot reach {what}: {exc.strerror or exc} (is it running? "
                         "`dask scheduler --host 127.0.0.1` starts one)") from None
    try:
        sock.settimeout(timeout)
        head = b""
        while len(head) < 8:
            got = sock.recv(8 - len(head))
            if not got:
                break
            head += got
    except OSError:
        head = b""
    finally:
        sock.close()
    if len(head) < 8 or not 0 < int.from_bytes(head, "little") < MAX_HANDSHAKE_BYTES:
        raise BenchError(f"{what} is not a Dask scheduler: something listens there but "
                         f"sent no Dask handshake within {timeout:g} s (an HTTP server? a "
                         "dashboard port?); give the scheduler's own port (default 8786)")


def cores() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def default_workers() -> int:
    """Two workers, or one on a one-core machine."""
    return max(1, min(2, cores()))


def check_workers(workers: int | None, scheduler: str | None = None) -> None:
    """BenchError (one line, before any work) for a worker count below 1, or above the
    cores this process may use when the workers would be local processes (500 workers on
    2 cores started 500 processes); the commands' default of 2 is not refused on one
    core (`Engine` starts no more local workers than cores). With a scheduler the
    workers are the cluster's."""
    if workers is None:
        return
    if workers < 1:
        raise BenchError(f"--workers must be >= 1, not {workers}")
    if scheduler_address(scheduler) is None and workers > max(cores(), 2):
        raise BenchError(f"--workers {workers}: this machine lets the bench use {cores()} "
                         f"core(s); at most {cores()} local worker processes (or give "
                         "--scheduler for a cluster's)")


class Engine:
    """A Dask client, on a LocalCluster of `workers` processes it owns or on the existing
    scheduler `scheduler`. With `wait=False` the cluster starts in a background thread
    (`client()` waits for it); `close()` stops what this engine started."""

    def __init__(self, workers: int, scheduler: str | None = None, wait: bool = True,
                 announce: bool = False, timeout: float | None = None) -> None:
        self.scheduler = scheduler_address(scheduler)
        self.workers = max(1, int(workers))
        if self.scheduler is None:          # never more local processes than cores
            self.workers = min(self.workers, cores())
        if self.scheduler is not None:
            check_address(self.scheduler)
        self.announce = announce
        self.timeout = timeout if timeout is not None else (
            START_TIMEOUT_S if self.scheduler is None else CONNECT_TIMEOUT_S)
        self.cluster: Any = None
        self.scratch: str | None = None    # the local cluster's scratch folder, removed on close
        self._client: Any = None
        self._error: BaseException | None = None
        self._lock = threading.Lock()
        self._closed = False              # close() was called
        self._done = False                # _start has finished (started or failed)
        self._thread = threading.Thread(target=self._start, name="bench-dask-start",
                                        daemon=True)
        self._thread.start()
        if wait:
            self.client()

    def _start(self) -> None:
        try:
            from distributed import Client
            if self.scheduler is not None:
                probe_scheduler(self.scheduler)
                self._client = Client(self.scheduler, timeout=self.timeout,
                                      set_as_default=False)
            else:
                self.scratch = tempfile.mkdtemp(prefix="bench-dask-")
                self.cluster = _local_cluster(self.workers, self.scratch)
                self._client = Client(self.cluster, set_as_default=False)
        except BaseException as exc:  # noqa: BLE001 - reported by client()
            self._error = exc
        with self._lock:
            self._done = True
            closed = self._closed
        if closed:                            # closed while starting
            self._shutdown()

    @property
    def start_finished(self) -> bool:
        """Whether the start has finished (started or failed), without waiting."""
        return self._done

    def client(self, announce: bool | None = None) -> Any:
        """The started `distributed.Client`; a cluster that does not start (or a
        scheduler that cannot be reached) is a BenchError, not a hang. With `announce`
        (default: the engine's) the dashboard link is printed on stderr, once per
        process."""
        self._thread.join(1.5 * self.timeout + 10.0)
        if self._thread.is_alive() or self._error is not None or self._client is None:
            if isinstance(self._error, BenchError):
                self.close()
                raise self._error
            why = ("timed out" if self._thread.is_alive() else
                   f"{type(self._error).__name__}: {self._error}")
            self.close()
            if self.scheduler is not None:
                raise BenchError(f"cannot use the Dask scheduler {self.scheduler} ({why})")
            raise BenchError(f"the Dask workers did not start ({why}); a script using "
                             "bench.gap or bench.hums with workers > 1 needs an `if "
                             "__name__ == '__main__':` guard, or use workers=1") from None
        shown = self.scheduler is not None or dashboard_available()
        if shown and (self.announce if announce is None else announce):
            link = self._client.dashboard_link
            if link not in _shown:
                _shown.add(link)
                print(f"dask dashboard: {link}", file=sys.stderr)
        return self._client

    def close(self) -> None:
        """Close the client and the cluster this engine started (an existing cluster is
        left running; its workers keep nothing of ours)."""
        with self._lock:
            self._closed = True
            done = self._done
        if done:                              # else the starting thread closes it
            self._shutdown()

    def _shutdown(self) -> None:
        client, cluster, self._client, self.cluster = self._client, self.cluster, None, None
        if client is not None:
            try:
                client.close(timeout=CLOSE_TIMEOUT_S)
            except Exception:  # noqa: BLE001 - best effort at the end of a job
                pass
        if cluster is not None:
            try:
                cluster.close(timeout=CLOSE_TIMEOUT_S)
            except Exception:  # noqa: BLE001 - best effort at the end of a job
                pass
        scratch, self.scratch = self.scratch, None
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _local_cluster(workers: int, scratch: str) -> Any:
    """A LocalCluster of `workers` single-threaded worker processes, every socket (the
    scheduler, the workers, the dashboard when bokeh is installed) on 127.0.0.1, its lock
    files and spill space in `scratch` (the engine's own temporary folder, removed when
    it closes; Dask's default is a shared dask-scratch-space that stays behind). The
    nannies set their pre-spawn variables in this process's environment to spawn the
    workers; they are put back afterwards, so that processes this one starts later do not inherit them (a nanny
    that restarts a dead worker sets them again)."""
    import dask
    from distributed import LocalCluster
    # the scheduler's folder follows the config, the workers' local_directory
    with environ_kept(PRE_SPAWN_VARS), dask.config.set({"temporary-directory": scratch}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            host="127.0.0.1", local_directory=scratch,
                            dashboard_address=DASHBOARD if dashboard_available() else None,
                            silence_logs=logging.CRITICAL,
                            env={k: "1" for k in THREAD_VARS})
