"""Shared set-up of the bus integration tests: a bus (the loopback hub always; vcan0 too
when TEST_SOCKETCAN=1, as python-can gates its socketcan suite) with a lockstep plant on
it, processes always stopped, every wait bounded."""

from __future__ import annotations

import contextlib
import os
import select
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import can

from bench.bus.procs import Child, start_hub, start_plant

ROOT = Path(__file__).resolve().parents[2]
BUS_KINDS = ["loopback"] + (["vcan0"] if os.environ.get("TEST_SOCKETCAN") == "1" else [])


@dataclass
class BusEnv:
    cfg: dict
    state: Path
    children: list[Child] = field(default_factory=list)
    prior_state_dir: str | None = None   # $BENCH_STATE_DIR before make_env, put back by stop

    @property
    def flags(self) -> list[str]:
        return ["-i", self.cfg["interface"], "-c", str(self.cfg["channel"])]

    @property
    def env(self) -> dict[str, str]:
        return {**os.environ, "BENCH_STATE_DIR": str(self.state)}

    def bus(self, **kw) -> can.BusABC:
        from ema_contract.transport import open_bus
        return open_bus(self.cfg, **kw)

    def stop(self) -> None:
        """Stop the children (last started first) and put $BENCH_STATE_DIR back."""
        for c in reversed(self.children):
            c.stop()
        if self.prior_state_dir is None:
            os.environ.pop("BENCH_STATE_DIR", None)
        else:
            os.environ["BENCH_STATE_DIR"] = self.prior_state_dir


def make_env(kind: str, state: Path, plant: bool = True, **plant_kw) -> BusEnv:
    """A bus (loopback hub or vcan0) and, with `plant`, a lockstep plant on it, with
    $BENCH_STATE_DIR set to `state` until the env's `stop`."""
    prior = os.environ.get("BENCH_STATE_DIR")
    os.environ["BENCH_STATE_DIR"] = str(state)
    if kind == "loopback":
        try:
            hub = start_hub(persistent=False)
        except Exception:
            BusEnv({}, state, prior_state_dir=prior).stop()
            raise
        env = BusEnv({"interface": "remote", "channel": hub.info["url"]}, state, [hub], prior)
    else:
        env = BusEnv({"interface": "socketcan", "channel": "vcan0"}, state,
                     prior_state_dir=prior)
    if plant:
        try:
            env.children.append(start_plant(env.cfg, pace="sync", **plant_kw))
        except Exception:
            env.stop()
            raise
    return env


def module_bus_env(request, tmp_path_factory):
    """Body of the module-scoped `bus_env` fixture of the bus test modules:
    ``yield from module_bus_env(request, tmp_path_factory)``."""
    env = make_env(request.param, tmp_path_factory.mktemp("state"))
    yield env
    env.stop()


def bench(*args: str, env: dict | None = None, timeout: float = 120.0
          ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True,
                          text=True, timeout=timeout, env=env, cwd=str(ROOT))


def spawn(*cmd: str, env: dict | None = None, **kw) -> subprocess.Popen:
    return subprocess.Popen(list(cmd), env=env, cwd=str(ROOT), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def file_size(path) -> int:
    """The size of `path`, 0 while it does not exist: the run's output probe creates a
    file and removes it again, so a check of exists() then stat() can race it."""
    try:
        return path.stat().st_size
    except FileNotFoundError:
        return 0


def wait_until(pred, timeout: float, what: str, step: float = 0.02):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = pred()
        if got:
            return got
        time.sleep(step)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


class Collector(can.Listener):
    """Frames seen by an independent bus client (a candump of the test)."""

    def __init__(self, env: BusEnv) -> None:
        self.bus = env.bus()
        self.msgs: list[can.Message] = []
        self.notifier = can.Notifier(self.bus, [self], timeout=0.02)

    def on_message_received(self, msg: can.Message) -> None:
        self.msgs.append(msg)

    def ids(self) -> list[int]:
        return [m.arbitration_id for m in self.msgs]

    def close(self) -> None:
        from ema_contract.transport import close_bus
        self.notifier.stop(1.0)
        close_bus(self.bus)


def wait_line(proc, needle: str, timeout: float) -> str:
    """The child's stderr up to the first line holding `needle` (AssertionError after
    `timeout` s or when the child exits)."""
    end = time.monotonic() + timeout
    seen = ""
    while time.monotonic() < end:
        r, _, _ = select.select([proc.stderr], [], [], 0.1)
        if r:
            line = proc.stderr.readline()
            seen += line
            if needle in line:
                return seen
        if proc.poll() is not None:
            break
    raise AssertionError(f"no {needle!r} from the watcher within {timeout} s: {seen}")


def watch_a_run(env: BusEnv, watch_flags: list[str], profile, values: dict, log_path: Path):
    """`bench hums watch --idle 2 WATCH_FLAGS` on `env`'s bus while one lockstep run of
    `profile` (plant `values`, logged to `log_path`) goes over it: the run's trace, and the
    watcher's exit status, standard output and standard error."""
    from bench.ecu import run_over_bus
    proc = spawn(sys.executable, "-m", "bench", "hums", "watch", "--idle", "2", *watch_flags,
                 *env.flags, env=env.env)
    try:
        wait_line(proc, "listening", 60)
        tr = run_over_bus(profile, values=values, pace="sync", settings=env.cfg,
                          log_path=log_path)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return tr, proc.returncode, out, err


def sdo_client(bus: can.BusABC, poll_s: float = 0.05):
    """The actuator (node 0x10, the contract's object dictionary) as a canopen remote
    node on `bus`, the network's notifier polling every `poll_s` s, SDO timeout 1 s:
    (network, node)."""
    import canopen

    from ema_contract.frames import load_od
    network = canopen.Network(bus)
    network.notifier = can.Notifier(network.bus, network.listeners, timeout=poll_s)
    node = canopen.RemoteNode(0x10, load_od())
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 1.0
    return network, node


@contextlib.contextmanager
def thread_hub():
    """A loopback hub served in a thread of this process, with its `url` and `kill()`:
    every connection dropped at once, as a killed hub does (again at the end)."""
    import threading

    from bench.bus.selecthub import SelectHub
    h = SelectHub()
    stop = threading.Event()
    th = threading.Thread(target=h.serve, args=(stop,), daemon=True)
    th.start()

    def kill() -> None:
        stop.set()
        th.join(5)

    h.kill = kill
    h.url = f"ws://127.0.0.1:{h.port}/"
    try:
        yield h
    finally:
        kill()


NODE_START_TIMEOUT_S = 90.0    # a first start may compile the plant (numba, cached on disk)


def start_node(name: str, module: list[str], cfg: dict, state: Path, *args: str) -> Child:
    """A node process (`python MODULE -i ... -c ... --ready-file ... ARGS`, this process its
    parent) on `cfg`, its stderr in STATE/NAME-*.log; waits (bounded) until it is on the
    bus, and says why not from its log."""
    ready = state / f"{name}-{time.monotonic_ns()}.ready"
    log = ready.with_suffix(".log")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    cmd = [sys.executable, *module, "-i", cfg["interface"], "-c", str(cfg["channel"]),
           "--ready-file", str(ready), "--parent-pid", str(os.getpid()), *args]
    with log.open("w") as err:
        proc = subprocess.Popen(cmd, env=env, cwd=str(ROOT), stdout=subprocess.DEVNULL,
                                stderr=err, stdin=subprocess.DEVNULL, start_new_session=True)
    child = Child(f"{name}-node", proc, proc.pid, log)
    end = time.monotonic() + NODE_START_TIMEOUT_S
    while not ready.exists():
        if proc.poll() is not None or time.monotonic() > end:
            child.stop()
            raise AssertionError(f"{name} node did not start: {log.read_text()[-2000:]}")
        time.sleep(0.05)
    return child
