"""Starting and stopping the bench's background processes: the loopback hub and the plant.

Every child is started in its own session (Ctrl-C in the terminal reaches only the
bench, which then stops its children itself) and is stopped by pid: SIGTERM, then
SIGKILL after a grace period. Ephemeral children (those `bench run` starts for one
run) are given ``--parent-pid`` so they also exit if the bench dies without cleaning up.
Nothing here waits without a time limit.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench import BenchError
from plant_rt.transport import pid_alive, state_dir

HUB_START_TIMEOUT_S = 10.0
PLANT_START_TIMEOUT_S = 90.0   # first start compiles the plant (numba, cached on disk)


@dataclass
class Child:
    """A process the bench started."""
    name: str
    proc: subprocess.Popen | None = None
    pid: int = 0
    log_path: Path | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def alive(self) -> bool:
        if self.proc is not None:
            return self.proc.poll() is None
        return pid_alive(self.pid)

    def stop(self, timeout: float = 3.0) -> bool:
        """SIGTERM, then SIGKILL after `timeout`; True if it was running."""
        return stop_pid(self.pid, timeout, self.proc)


def stop_pid(pid: int, timeout: float = 3.0, proc: subprocess.Popen | None = None) -> bool:
    if pid <= 0 or not pid_alive(pid):
        if proc is not None:
            proc.poll()
        return False
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return False
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc is not None and proc.poll() is not None:
            return True
        if proc is None and not pid_alive(pid):
            return True
        time.sleep(0.02)
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    if proc is not None:
        try:
            proc.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            pass
    return True


def _tail(path: Path | None, n: int = 5) -> str:
    if path is None or not path.exists():
        return ""
    lines = [ln for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    return "\n".join(lines[-n:])


def _log_file(name: str, persistent: bool) -> Path:
    d = state_dir() if persistent else state_dir() / "run"
    d.mkdir(parents=True, exist_ok=True)
    return d / (f"{name}.log" if persistent else f"{name}-{os.getpid()}.log")


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
        raise BenchError(f"the loopback hub did not start: {_tail(log_path) or 'no output'}")
    proc.stdout.close()
    return Child("hub", proc, proc.pid, log_path, {"url": url})


def plant_command(cfg: dict[str, Any], pace: str = "sync", assignments: list[str] | None = None,
                  ready_file: Path | None = None, parent_pid: int | None = None,
                  node_id: int | None = None, extra: list[str] | None = None) -> list[str]:
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
    return cmd + list(extra or [])


def start_plant(cfg: dict[str, Any], pace: str = "sync", assignments: list[str] | None = None,
                persistent: bool = False, node_id: int | None = None,
                timeout: float = PLANT_START_TIMEOUT_S) -> Child:
    """Start the plant node on `cfg` and wait until it has booted."""
    log_path = _log_file("plant", persistent)
    ready = log_path.with_suffix(".ready")
    ready.unlink(missing_ok=True)
    cmd = plant_command(cfg, pace, assignments, ready,
                        None if persistent else os.getpid(), node_id)
    with log_path.open("w") as err:
        proc = subprocess.Popen(cmd, stdout=err, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if ready.exists():
            ready.unlink(missing_ok=True)
            return Child("plant", proc, proc.pid, log_path, {"pace": pace})
        if proc.poll() is not None:
            raise BenchError(f"the plant exited at start: {_tail(log_path) or 'no output'}")
        time.sleep(0.02)
    stop_pid(proc.pid, 1.0, proc)
    raise BenchError(f"the plant did not boot within {timeout:.0f} s: {_tail(log_path)}")
