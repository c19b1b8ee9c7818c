"""Soak benchmark: a long lockstep run with a flood client and a slow reader.

    python benchmarks/bench_soak.py [--periods 1000000] [--flood-rate 2000]
                                    [--write docs/performance.md] [--json OUT]

Runs the same scenario twice on a fresh loopback hub and plant each time (the sine
profile in lockstep, sensor noise on, fixed seeds):

1. undisturbed;
2. with two hostile local clients on the hub for the whole run: a *flood client* that
   sends frames the bench does not use (extended id 0x1ABCDE0 + k, 8 bytes) at
   ``--flood-rate`` frames/s, and a *slow reader* that joins the bus and never reads
   (its socket buffers are made small, so the hub has to queue or drop for it; when the
   hub drops it, it joins again after 2 s).

Hub and plant RSS are sampled every second (VmRSS from /proc). The result states: the
maximum RSS of each, the growth from 10 % of the run to its end (flat: a few MB), lost
frames in the disturbed run (lost SYNCs, missing TPDO/RPDO, late TPDO sets), and whether
the disturbed run's log equals the undisturbed one: the decoded trace exactly, and the
frame sequence (id and data, in order) without heartbeats (wall-clock timed), SDO (the
counters read after the run hold wall-clock statistics) and the flood's frames. Everything runs on 127.0.0.1, in processes this script starts and
stops by PID; the flood and the slow reader stop when the run ends.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import select
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import perfdoc  # noqa: E402

from bench import machine_description  # noqa: E402

SECTION = "## Soak"
FLOOD_ID0 = 0x1ABCDE0

FLOOD = r"""
import signal, sys, time, can
sys.path.insert(0, sys.argv[3])
stop = []
signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
from plant_rt.pacing import RealtimePacer
url, rate = sys.argv[1], float(sys.argv[2])
# an acceptance filter for an id nobody sends: the flood only sends (a client that
# never reads what the hub forwards to it is a slow reader, and the hub drops it)
bus = can.Bus(interface="remote", channel=url,
              can_filters=[{"can_id": 0x1FFFFFFF, "can_mask": 0x1FFFFFFF, "extended": True}])
print("ready", flush=True)
sent, k = 0, 0
burst = max(1, int(rate / 100))             # 100 bursts per second
pacer = RealtimePacer(burst / rate, 0.0)
pacer.start(0.01)
try:
    while not stop:
        pacer.wait()
        for _ in range(burst):
            bus.send(can.Message(arbitration_id=0x1ABCDE0 + (k & 0xF), is_extended_id=True,
                                 data=k.to_bytes(8, "little")))
            k += 1
        pacer.done()
except Exception as exc:  # the hub went away, or dropped us: said in the results
    print(f"flood ended early: {type(exc).__name__}: {exc}", flush=True)
print(f"sent {k}", flush=True)
try:
    bus.shutdown()
except Exception:
    pass
"""


def rss_kb(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


class RssSampler(threading.Thread):
    def __init__(self, pids: dict[str, int], period_s: float = 1.0) -> None:
        super().__init__(daemon=True)
        self.pids, self.period_s = pids, period_s
        self.samples: dict[str, list[tuple[float, int]]] = {k: [] for k in pids}
        self.stop = threading.Event()

    def run(self) -> None:
        t0 = time.monotonic()
        while not self.stop.wait(self.period_s):
            for name, pid in self.pids.items():
                self.samples[name].append((time.monotonic() - t0, rss_kb(pid)))

    def summary(self) -> dict[str, dict[str, float]]:
        out = {}
        for name, s in self.samples.items():
            vals = [v for _, v in s if v > 0]
            if not vals:
                out[name] = {"max_mb": float("nan"), "growth_mb": float("nan")}
                continue
            i10 = len(vals) // 10
            out[name] = {"max_mb": max(vals) / 1024, "start_mb": vals[i10] / 1024,
                         "end_mb": vals[-1] / 1024,
                         "growth_mb": (vals[-1] - vals[i10]) / 1024, "samples": len(vals)}
        return out


class SlowReader(threading.Thread):
    """Joins the hub's bus with a tiny receive buffer and never reads."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.port = port
        self.stop = threading.Event()
        self.joins = 0
        self.dropped = 0

    def _join(self) -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.connect(("127.0.0.1", self.port))
        key = base64.b64encode(os.urandom(16)).decode()
        s.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{self.port}\r\nUpgrade: websocket\r\n"
                   f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                   "Sec-WebSocket-Version: 13\r\n"
                   "Sec-WebSocket-Protocol: can.binary+json.v1\r\n\r\n").encode())
        payload = json.dumps({"type": "bus_request", "payload": {"config": {}}}).encode()
        mask = os.urandom(4)
        body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        head = bytes((0x81, 0x80 | 126)) + struct.pack(">H", len(body)) if len(body) > 125 \
            else bytes((0x81, 0x80 | len(body)))
        s.sendall(head + mask + body)
        self.joins += 1
        return s

    def run(self) -> None:
        s = self._join()
        while not self.stop.wait(2.0):
            # still connected? POLLRDHUP tells a peer's close even with unread data queued
            # (a MSG_PEEK would see the data and miss the close)
            poller = select.poll()
            poller.register(s, select.POLLRDHUP | select.POLLHUP | select.POLLERR)
            if poller.poll(0):
                self.dropped += 1
                s.close()
                try:
                    s = self._join()
                except OSError:
                    return
        s.close()


def one_run(periods: int, log: Path, disturbed: bool, flood_rate: float) -> dict:
    from bench.bus.logs import trace_from_log  # noqa: F401  (imported before the clock)
    from bench.bus.procs import start_hub, start_plant
    from bench.ecu import run_over_bus
    from bench.profiles.catalog import make_profile

    hub = start_hub(persistent=False)
    url = hub.info["url"]
    port = int(url.rsplit(":", 1)[1].strip("/"))
    cfg = {"interface": "remote", "channel": url}
    flood = reader = None
    res: dict = {"disturbed": disturbed, "periods": periods}
    try:
        plant = start_plant(cfg, pace="sync", assignments=["sensors.noise=on"])
        sampler = RssSampler({"hub": hub.pid, "plant": plant.pid})
        try:
            if disturbed:
                flood = subprocess.Popen([sys.executable, "-c", FLOOD, url, str(flood_rate),
                                          str(ROOT)], stdout=subprocess.PIPE, text=True)
                assert flood.stdout is not None and flood.stdout.readline().strip() == "ready"
                reader = SlowReader(port)
                reader.start()
            sampler.start()
            t0 = time.monotonic()
            tr = run_over_bus(make_profile("sine", duration_s=periods * 1e-3), pace="sync",
                              settings=cfg, log_path=log, progress=sys.stderr.isatty(),
                              values={"sensors.noise": "on"})
            res["wall_s"] = time.monotonic() - t0
        finally:
            sampler.stop.set()
            if reader is not None:
                reader.stop.set()
            if flood is not None:
                flood.terminate()
                try:
                    out = flood.communicate(timeout=10)[0]
                except subprocess.TimeoutExpired:
                    flood.kill()
                    out = flood.communicate()[0]
                sent = [ln for ln in out.splitlines() if ln.startswith("sent")]
                res["flood_sent"] = int(sent[-1].split()[1]) if sent else None
                res["flood_ended_early"] = [ln for ln in out.splitlines()
                                            if ln.startswith("flood ended early")]
            plant.stop()
        res["rss"] = sampler.summary()
    finally:
        hub.stop()
    if reader is not None:
        res["slow_reader_joins"] = reader.joins
        res["slow_reader_dropped_by_hub"] = reader.dropped
    ecu, pc = tr.meta["ecu"], tr.meta["plant_counters"]
    res["complete"] = bool(tr.meta.get("complete"))
    res["rows"] = len(tr)
    res["late_tpdo"] = ecu.get("late_tpdo")
    res["plant"] = {k: pc.get(k) for k in ("sync_received", "rpdo_missing", "sync_counter_gaps",
                                           "bad_frames", "unknown_frames", "heartbeat_timeouts",
                                           "emcy_sent")} if isinstance(pc, dict) else pc
    return res


def frames_of(path: Path):
    """(id, data) of every frame of a log but heartbeats (wall-clock timed), SDO (the
    counters read after the run hold wall-clock statistics) and the flood, in order."""
    from bench.bus.logs import read_log
    for m in read_log(path):
        cid = m.arbitration_id
        if m.is_extended_id and FLOOD_ID0 <= cid < FLOOD_ID0 + 16:
            continue
        if not m.is_extended_id and (0x700 <= cid <= 0x77F or 0x580 <= cid <= 0x67F):
            continue
        yield cid, bytes(m.data)


def compare(a: Path, b: Path) -> dict:
    import itertools

    import numpy as np

    from bench.bus.logs import trace_from_log
    ta, tb = trace_from_log(a), trace_from_log(b)
    same_cols = sorted(ta.columns) == sorted(tb.columns) and len(ta) == len(tb)
    diff_cols = []
    if same_cols:
        for c in ta.columns:
            if c in ("t_s", "bus_time_s"):
                continue
            if not np.array_equal(np.asarray(ta[c]), np.asarray(tb[c]), equal_nan=True):
                diff_cols.append(c)
    n = mismatch = 0
    first = None
    for fa, fb in itertools.zip_longest(frames_of(a), frames_of(b)):
        n += 1
        if fa != fb:
            mismatch += 1
            if first is None:
                first = (n, fa, fb)
    return {"rows": [len(ta), len(tb)], "trace_equal": same_cols and not diff_cols,
            "columns_differing": diff_cols, "frames_compared": n, "frames_differing": mismatch,
            "first_difference": None if first is None else
            f"frame {first[0]}: {first[1]} vs {first[2]}",
            "lost": {k: [ta.meta.get(k), tb.meta.get(k)] for k in ta.meta
                     if "lost" in k or "missing" in k or "duplicate" in k}}


def write_section(path: Path, res: dict) -> None:
    a, b, c = res["undisturbed"], res["disturbed"], res["compare"]
    L = [SECTION, "",
         f"Measured by `python benchmarks/bench_soak.py --periods {res['periods']} --write "
         f"docs/performance.md` on {res['machine']}: the sine profile in lockstep with sensor "
         f"noise, {res['periods']:,} periods ({res['periods'] / 1000:,.0f} s of bus time), "
         "once undisturbed and once with a flood client "
         f"({res['flood_rate']:,.0f} frames/s of an unused extended id, "
         f"{b.get('flood_sent') or 0:,} frames sent) and a slow reader that never reads "
         "(4 KiB receive buffer; it joins again when the hub drops it) on the same hub.", "",
         "| run | wall | hub RSS max | hub growth 10 %->end | plant RSS max | "
         "plant growth | late TPDO sets | plant: RPDO missing / SYNC gaps |",
         "|---|---|---|---|---|---|---|---|"]
    for name, r in (("undisturbed", a), ("flood + slow reader", b)):
        h, p = r["rss"]["hub"], r["rss"]["plant"]
        pl = r["plant"] if isinstance(r["plant"], dict) else {}
        L.append(f"| {name} | {r['wall_s']:.0f} s | {h['max_mb']:.1f} MB | "
                 f"{h['growth_mb']:+.1f} MB | {p['max_mb']:.1f} MB | {p['growth_mb']:+.1f} MB | "
                 f"{r['late_tpdo']} | {pl.get('rpdo_missing')} / "
                 f"{pl.get('sync_counter_gaps')} |")
    early = b.get("flood_ended_early")
    L += ["", ("The flood ran for the whole run. " if not early else
               f"The flood ended early ({early[0]}): this run does not show the goal. ")
          + f"Slow reader: joined {b.get('slow_reader_joins')} times, dropped by the hub "
          f"{b.get('slow_reader_dropped_by_hub')} times. Disturbed log against the "
          f"undisturbed one: decoded trace {'identical' if c['trace_equal'] else 'DIFFERENT'}"
          f" ({c['rows'][0]:,} rows each"
          + (f"; columns differing: {', '.join(c['columns_differing'])}"
             if c["columns_differing"] else "")
          + f"); frame sequence without heartbeats, SDO and flood: {c['frames_compared']:,} frames, "
          f"{c['frames_differing']} differing"
          + (f" (first: {c['first_difference']})" if c["first_difference"] else "") + ".", ""]
    perfdoc.write_section(path, "\n".join(L))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Soak benchmark.")
    ap.add_argument("--periods", type=int, default=1_000_000,
                    help="lockstep periods of each run (default: %(default)s)")
    ap.add_argument("--flood-rate", type=float, default=2000.0,
                    help="frames per second of the flood client (default: %(default)s)")
    ap.add_argument("--write", metavar="MD", help="update the Soak section of this markdown")
    ap.add_argument("--json", metavar="OUT", help="write the raw results as JSON")
    ap.add_argument("--keep", metavar="DIR", help="keep the two logs (and each run's "
                    "results, RUN.json) in DIR")
    ap.add_argument("--reuse-undisturbed", action="store_true",
                    help="with --keep: take the undisturbed run from DIR (undisturbed.log and "
                         "undisturbed.json of an earlier run of the same code) instead of "
                         "running it again")
    args = ap.parse_args(argv)
    if args.periods < 1000 or not 0 < args.flood_rate <= 50_000:
        ap.error("--periods must be >= 1000 and --flood-rate within (0, 50000]")
    os.environ.setdefault("BENCH_STATE_DIR", tempfile.mkdtemp(prefix="bench-soak-"))
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-soak-logs-"))
    work.mkdir(parents=True, exist_ok=True)
    res: dict = {"machine": machine_description(), "periods": args.periods,
                 "flood_rate": args.flood_rate}
    for key, disturbed in (("undisturbed", False), ("disturbed", True)):
        saved = work / f"{key}.json"
        if key == "undisturbed" and args.reuse_undisturbed and saved.exists():
            res[key] = json.loads(saved.read_text())
            if res[key].get("periods") != args.periods:
                ap.error(f"{saved} holds a run of {res[key].get('periods')} periods")
            print(f"undisturbed run taken from {saved}", flush=True)
            continue
        print(f"{key} run of {args.periods:,} periods ...", flush=True)
        res[key] = one_run(args.periods, work / f"{key}.log", disturbed, args.flood_rate)
        if args.keep:
            saved.write_text(json.dumps(res[key], indent=1))
        print(json.dumps(res[key], indent=1), flush=True)
    res["compare"] = compare(work / "undisturbed.log", work / "disturbed.log")
    print(json.dumps(res["compare"], indent=1), flush=True)
    if not args.keep:
        for f in work.glob("*.log"):
            f.unlink()
        work.rmdir()
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2))
    if args.write:
        write_section(Path(args.write), res)
        print(f"wrote {args.write}")
    ok = (res["compare"]["trace_equal"] and res["compare"]["frames_differing"] == 0
          and not res["disturbed"].get("flood_ended_early"))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
