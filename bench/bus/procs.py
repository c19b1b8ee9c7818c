"""Starting and stopping the bench's background processes: the loopback hub and the plant.

Every child is started in its own session (Ctrl-C in the terminal reaches only the
bench, which then stops its children itself) and is stopped by pid: SIGTERM, then
SIGKILL after a grace period. Ephemeral children (those `bench run` starts for one
run) are given ``--parent-pid`` so they also exit if the bench dies without cleaning up.
Nothing here waits without a time limit.
"""

from __future__ import annotations

import itertools
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench import BenchError
from ema_contract.transport import is_process, pid_alive, process_token, state_dir

HUB_START_TIMEOUT_S = 10.0
PLANT_START_TIMEOUT_S = 90.0   # first start compiles the plant (numba, cached on disk)
KEEP_RUN_LOGS = 10             # logs of failed commands kept in the run directory
_RUN_SEQ = itertools.count(1)


@dataclass
class Child:
    """A process the bench started (`token`: its identity, `ema_contract.transport.process_token`)."""
    name: str
    proc: subprocess.Popen | None = None
    pid: int = 0
    log_path: Path | None = None
    info: dict[str, Any] = field(default_factory=dict)
    token: str | None = None
    ephemeral: bool = False    # started for one command: its log is in run_dir()

    def alive(self) -> bool:
        if self.proc is not None:
            return self.proc.poll() is None
        return is_process(self.pid, self.token, MODULES.get(self.name))

    def stop(self, timeout: float = 3.0) -> bool:
        """SIGTERM, then SIGKILL after `timeout`; True if it was running."""
        return stop_pid(self.pid, timeout, self.proc, self.token, MODULES.get(self.name))

    def remove_log(self) -> None:
        """Remove the log of an ephemeral child (once it has ended well)."""
        if self.ephemeral and self.log_path is not None:
            self.log_path.unlink(missing_ok=True)


MODULES = {"hub": "bench.bus.hub", "plant": "plant_rt"}


def stop_pid(pid: int, timeout: float = 3.0, proc: subprocess.Popen | None = None,
             token: str | None = None, module: str | None = None) -> bool:
    """Stop process `pid`: SIGTERM, then SIGKILL after `timeout` s; True if it was running.

    Nothing is signalled unless the process is known to be the one meant: `proc` (our own
    child, which Popen never lets us confuse with a reused pid), else a live process whose
    identity token equals `token` or, without a token, whose command line runs `module`
    (`ema_contract.transport.is_process`). Each signal is preceded by that check."""
    if proc is not None:
        return _stop_child(proc, timeout)
    if not is_process(pid, token, module):
        return False
    _signal(pid, signal.SIGTERM)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if not is_process(pid, token, module):
            return True
        time.sleep(0.02)
    if is_process(pid, token, module):
        _signal(pid, signal.SIGKILL)
    return True


def _signal(pid: int, sig: int) -> None:
    try:
        os.kill(pid, sig)
    except ProcessLookupError:
        pass


def _stop_child(proc: subprocess.Popen, timeout: float) -> bool:
    """SIGTERM, SIGKILL after `timeout` s, for a child of ours (reaped here)."""
    if proc.poll() is not None:
        return False
    proc.terminate()
    try:
        proc.wait(timeout=timeout)
        return True
    except subprocess.TimeoutExpired:
        pass
    proc.kill()
    try:
        proc.wait(timeout=2.0)
    except subprocess.TimeoutExpired:
        pass
    return True


def _last_words(path: Path) -> str:
    """The last line a child wrote to its log, and where the log is (kept for reading)."""
    lines = []
    if path.exists():
        lines = [ln for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    return f"{lines[-1].strip() if lines else 'no output'} (log: {path})"


def run_dir() -> Path:
    """Where the hubs and plants started for one command write their logs."""
    return state_dir() / "run"


def _owner(path: Path) -> int | None:
    """The pid of the bench that wrote run log NAME-PID[-N].log (None if not such a name)."""
    try:
        return int(path.stem.split("-")[1])
    except (IndexError, ValueError):
        return None


def prune_run_logs(d: Path, keep: int = KEEP_RUN_LOGS) -> None:
    """Keep the newest `keep` logs of benches that are gone (those of failed commands;
    one that ended well removed its own) and every log of a bench still running."""
    gone = []
    for p in d.glob("*-*.*"):
        owner = _owner(p)
        if owner is None or pid_alive(owner):     # a reused pid only keeps a log longer
            continue
        if p.suffix == ".ready":
            p.unlink(missing_ok=True)
        elif p.suffix == ".log":
            gone.append(p)
    gone.sort(key=lambda p: p.stat().st_mtime if p.exists() else 0.0, reverse=True)
    for p in gone[keep:]:
        p.unlink(missing_ok=True)


def _log_file(name: str, persistent: bool) -> Path:
    if persistent:
        d = state_dir()
        d.mkdir(mode=0o700, parents=True, exist_ok=True)
        return d / f"{name}.log"
    d = run_dir()
    d.mkdir(mode=0o700, parents=True, exist_ok=True)
    prune_run_logs(d)
    return d / f"{name}-{os.getpid()}-{next(_RUN_SEQ)}.log"   # one per start: none clobbered


def start_hub(persistent: bool = False, timeout: float = HUB_START_TIMEOUT_S,
              server: str | None = None) -> Child:
    """Start the loopback hub (recorded in the state directory when `persistent`).

    `server` is "select" (default) or "can_remote" (also from $BENCH_HUB_SERVER)."""
    server = server or os.environ.get("BENCH_HUB_SERVER", "select")
    cmd = [sys.executable, "-m", "bench.bus.hub", "--server", server]
    if not persistent:
        cmd += ["--no-state", "--parent-pid", str(os.getpid())]
    log_path = _log_file("hub", persistent)
    with log_path.open("w") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, stdin=subprocess.DEVNULL,
                                start_new_session=True, text=True)
    assert proc.stdout is not None
    end = time.monotonic() + timeout
    url = ""
    while time.monotonic() < end:
        ready, _, _ = select.select([proc.stdout], [], [], 0.1)
        if ready:
            url = proc.stdout.readline().strip()
            break
        if proc.poll() is not None:
            break
    if not url.startswith("ws://"):
        stop_pid(proc.pid, 1.0, proc)
        raise BenchError(f"the loopback hub did not start: {_last_words(log_path)}")
    proc.stdout.close()
    return Child("hub", proc, proc.pid, log_path, {"url": url}, process_token(proc.pid),
                 ephemeral=not persistent)


def plant_command(cfg: dict[str, Any], pace: str = "sync", assignments: list[str] | None = None,
                  ready_file: Path | None = None, parent_pid: int | None = None,
                  node_id: int | None = None, extra: list[str] | None = None,
                  serial: int | None = None) -> list[str]:
    """The command line starting the plant node on the bus `cfg`."""
    cmd = [sys.executable, "-m", "plant_rt", "--pace", pace]
    for key, flag in (("interface", "-i"), ("channel", "-c"), ("bitrate", "-b")):
        if cfg.get(key) is not None:
            cmd += [flag, str(cfg[key])]
    kwargs = {k: v for k, v in cfg.items()
              if k not in ("interface", "channel", "bitrate") and v is not None
              and isinstance(v, (str, int, float, bool))}
    if kwargs:
        cmd += ["--bus-kwargs", *[f"{k}={v}" for k, v in kwargs.items()]]
    for a in assignments or []:
        cmd += ["--set", a]
    if ready_file is not None:
        cmd += ["--ready-file", str(ready_file)]
    if parent_pid is not None:
        cmd += ["--parent-pid", str(parent_pid)]
    if node_id is not None:
        cmd += ["--node-id", str(node_id)]
    if serial is not None:
        cmd += ["--serial", str(serial)]
    return cmd + list(extra or [])


def start_plant(cfg: dict[str, Any], pace: str = "sync", assignments: list[str] | None = None,
                persistent: bool = False, node_id: int | None = None,
                timeout: float = PLANT_START_TIMEOUT_S, serial: int | None = None,
                on_wait: Callable[[float], None] | None = None) -> Child:
    """Start the plant node on `cfg` and wait until it has booted; `on_wait(elapsed_s)`
    is called while waiting (every 20 ms), for a progress display."""
    log_path = _log_file("plant", persistent)
    ready = log_path.with_suffix(".ready")
    ready.unlink(missing_ok=True)
    cmd = plant_command(cfg, pace, assignments, ready,
                        None if persistent else os.getpid(), node_id, serial=serial)
    with log_path.open("w") as err:
        proc = subprocess.Popen(cmd, stdout=err, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)
    t0 = time.monotonic()
    end = t0 + timeout
    while time.monotonic() < end:
        if ready.exists():
            ready.unlink(missing_ok=True)
            return Child("plant", proc, proc.pid, log_path, {"pace": pace},
                         process_token(proc.pid), ephemeral=not persistent)
        if proc.poll() is not None:
            raise BenchError(f"the plant exited at start: {_last_words(log_path)}")
        if on_wait is not None:
            on_wait(time.monotonic() - t0)
        time.sleep(0.02)
    stop_pid(proc.pid, 1.0, proc)
    raise BenchError(f"the plant did not boot within {timeout:.0f} s: {_last_words(log_path)}")
