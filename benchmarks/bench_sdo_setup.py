"""SDO set-up on a loaded machine: how often a run's set-up fails, and its round trips.

    python benchmarks/bench_sdo_setup.py [--runs 20] [--listeners 2] [--json OUT]

Starts a loopback hub and a lockstep plant (as `bench up --pace sync`), and `--listeners`
passive clients that read every frame (as `bench log`); then runs `--runs` times the
set-up and a 3-cycle sine (`bench run sine --pace sync --cycles 3`, in-process through
`bench.ecu.run_over_bus`) with a log, and reports the runs that failed (with their error),
the transfers started again (`meta["ecu"]["sdo_retries"]`) and the SDO round trips read
from the logs (request 0x600+id to the next answer 0x580+id): p50, p90, p99, max. The
load average is printed next to each run; load the machine first (other work, or a CPU
hog) to measure under load. Everything started here is stopped here.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import can  # noqa: E402
import numpy as np  # noqa: E402

from bench import BenchError  # noqa: E402
from bench.bus.procs import start_hub, start_plant  # noqa: E402
from bench.ecu import run_over_bus  # noqa: E402
from bench.profiles.catalog import make_profile  # noqa: E402
from ema_contract.transport import close_bus, open_bus  # noqa: E402


def round_trips(log: Path, node_id: int = 0x10) -> list[float]:
    """SDO round trips (s) in a candump log: each request to the next answer."""
    out, t_req = [], None
    with can.LogReader(log) as reader:
        for m in reader:
            if m.arbitration_id == 0x600 + node_id:
                t_req = m.timestamp
            elif m.arbitration_id == 0x580 + node_id and t_req is not None:
                out.append(m.timestamp - t_req)
                t_req = None
    return out


def _listen(cfg: dict, stop: threading.Event) -> None:
    bus = open_bus(cfg)
    try:
        while not stop.is_set():
            bus.recv(0.05)
    finally:
        close_bus(bus)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--listeners", type=int, default=2)
    ap.add_argument("--json", metavar="OUT")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-sdo-"))
    os.environ["BENCH_STATE_DIR"] = str(tmp / "state")
    hub = start_hub(persistent=False)
    cfg = {"interface": "remote", "channel": hub.info["url"]}
    children, stop, threads = [hub], threading.Event(), []
    results = []
    try:
        children.append(start_plant(cfg, pace="sync"))
        for _ in range(args.listeners):
            th = threading.Thread(target=_listen, args=(cfg, stop), daemon=True)
            th.start()
            threads.append(th)
        profile = make_profile("sine", cycles=3)
        rtt: list[float] = []
        for i in range(args.runs):
            load = os.getloadavg()[0]
            log = tmp / f"run{i}.log"
            try:
                tr = run_over_bus(profile, pace="sync", settings=cfg, log_path=log,
                                  start_plant=False)
                res = {"load": load, "ok": True, "retries": tr.meta["ecu"]["sdo_retries"]}
            except BenchError as exc:
                res = {"load": load, "ok": False, "error": str(exc)}
            if log.exists():
                rtt += round_trips(log)
            results.append(res)
            print(f"run {i + 1}: load {load:.1f}: "
                  + ("ok" if res["ok"] else f"FAILED: {res['error']}")
                  + (f", {res['retries']} transfers repeated" if res.get("retries") else ""),
                  flush=True)
    finally:
        stop.set()
        for th in threads:
            th.join(2.0)
        for c in reversed(children):
            c.stop()
    ms = np.array(rtt) * 1e3
    summary = {"runs": len(results), "failed": sum(not r["ok"] for r in results),
               "retries": sum(r.get("retries", 0) for r in results),
               "round_trips": len(ms), "p50_ms": float(np.percentile(ms, 50)),
               "p90_ms": float(np.percentile(ms, 90)), "p99_ms": float(np.percentile(ms, 99)),
               "max_ms": float(ms.max()), "runs_detail": results}
    print(f"{summary['failed']} of {summary['runs']} runs failed, {summary['retries']} "
          f"transfers repeated; {summary['round_trips']} SDO round trips: p50 "
          f"{summary['p50_ms']:.1f} ms, p90 {summary['p90_ms']:.1f} ms, p99 "
          f"{summary['p99_ms']:.1f} ms, max {summary['max_ms']:.1f} ms")
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
