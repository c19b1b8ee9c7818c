"""Fleet benchmark: ingest throughput on 1 and 2 workers, a synthetic fleet end
to end (synth + ingest) with the peak memory of the process tree, `bench fleet status`
on that store and on a 10,000-run store, bytes per stored run.

Every stage runs the real CLI (`python -m bench fleet ...`) as a subprocess, timed on the
wall clock; the peak RSS is the largest sum of the resident sets of the stage's process
and all its descendants, sampled every 0.2 s from /proc.

    python benchmarks/bench_fleet.py --actuators 30 --days 20 --write docs/performance.md
    python benchmarks/bench_fleet.py --actuators 100 --days 100     # the full 10,000 logs

The 10,000-run store for the status timing is built from the measured store by copying
its runs under new digests and actuator ids (a status reads only the stored rows).

Every stage, and the in-process cost measurement, runs with one BLAS/OpenMP/numba thread
(`bench.runtime.cluster.THREAD_VARS` = 1, as the Dask workers run): one worker is one core, also
for the 1-worker ingest, which runs in the CLI's own process (with OpenBLAS' default two
threads the HUMS analysis of a log spends ~4x the CPU spinning, and the 1-worker row
would measure a worker on two cores).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perfdoc import write_section  # noqa: E402

from bench.runtime.cluster import THREAD_VARS  # noqa: E402  (imports neither numpy nor dask)

for _var in THREAD_VARS:             # before numpy is imported: one thread per process
    os.environ[_var] = "1"

ROOT = Path(__file__).resolve().parents[1]


def _tree_rss(pid: int) -> int:
    """Resident set of `pid` and its descendants, bytes."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        kids.setdefault(ppid, []).append(int(d))
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        todo.extend(kids.get(p, []))
        try:
            with open(f"/proc/{p}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        total += int(line.split()[1]) * 1024
        except OSError:
            pass
    return total


def run(args: list[str]) -> tuple[float, int, str]:
    """Wall time, peak tree RSS and stdout of `python -m bench fleet ARGS`."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "bench", "fleet", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    peak = [0]

    def sample() -> None:
        while proc.poll() is None:
            peak[0] = max(peak[0], _tree_rss(proc.pid))
            time.sleep(0.2)

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    out, _ = proc.communicate()
    dt = time.perf_counter() - t0
    th.join()
    if proc.returncode:
        raise SystemExit(f"bench fleet {' '.join(args)}: exit {proc.returncode}")
    return dt, peak[0], out


def grow_store(src: Path, dst: Path, target: int) -> int:
    """A copy of `src` with its runs copied under new digests and actuator ids until it
    holds `target` runs (for the status timing)."""
    import duckdb
    shutil.copy(src, dst)
    con = duckdb.connect(str(dst))
    n = con.execute("SELECT count(*) FROM runs").fetchone()[0]
    k = 1
    while n < target:
        con.execute("INSERT INTO runs SELECT * REPLACE (digest || ?  AS digest, "
                    "actuator_id || ? AS actuator_id) FROM runs WHERE NOT contains(digest, '/')"
                    f" LIMIT {target - n}", [f"/{k}", f"-copy{k}"])
        n = con.execute("SELECT count(*) FROM runs").fetchone()[0]
        k += 1
    con.close()
    return int(n)


def ingest_cost(logdir: Path, n: int = 44) -> dict[str, float]:
    """CPU and wall time per log of `bench.fleet.ingest.ingest_one` in this process,
    after one warm-up log (imports, compilation, gain fit)."""
    from bench.fleet.ingest import digest, ingest_one
    files = sorted(logdir.rglob("*.log"))[:n + 1]
    ingest_one((str(files[0]), digest(files[0]), None))
    w0, c0 = time.perf_counter(), time.process_time()
    for f in files[1:]:
        ingest_one((str(f), digest(f), None))
    k = len(files) - 1
    return {"cpu_per_log_s": (time.process_time() - c0) / k,
            "wall_per_log_s": (time.perf_counter() - w0) / k, "cpu_load": os.getloadavg()[0]}


def synth_cost(n: int = 10) -> dict[str, float]:
    """CPU time per log of `bench.fleet.synth._job` (simulate + write_candump) and of
    write_candump alone in this process, after one warm-up log."""
    from bench.fleet import synth as S
    from bench.profiles.catalog import sine
    from bench.sim.harness import simulate
    from plant_rt.params import PlantParams
    act = S.draw_fleet(1, n, 0)[0]
    with tempfile.TemporaryDirectory(prefix="bench-fleet-cost-") as tmp:
        jobs = [(f"{tmp}/{d}.log", S.wear_at(act, d), d, 1.7e9 + d * 86400.0, act.ident)
                for d in range(n + 1)]
        S._job(jobs[0])
        c0 = time.process_time()
        for job in jobs[1:]:
            S._job(job)
        job_s = (time.process_time() - c0) / n
        p = PlantParams().with_dict({**jobs[1][1], "sensors.noise": True,
                                     "sensors.noise_seed": 1})
        tr = simulate(sine(cycles=S.GROUND_TEST_CYCLES), p)
        c0 = time.process_time()
        for d in range(n):
            S.write_candump(tr, f"{tmp}/w{d}.log", 1.7e9 + d)
        write_s = (time.process_time() - c0) / n
    return {"synth_cpu_per_log_s": job_s, "write_cpu_per_log_s": write_s}


def rul_check(db: Path) -> dict[str, float]:
    """The fleet RUL (`bench.fleet.status.rul_of`) re-made after every test of each
    actuator that reached the failure level, from the tests up to then only, against the
    day it did reach it: predictions made, median |error| (days), share in the band."""
    import duckdb
    import numpy as np

    from bench.fleet.status import DAY_S, floats, judged_ci, rul_of
    from bench.hums import rul as R
    con = duckdb.connect(str(db), read_only=True)
    d = con.execute("SELECT actuator_id, epoch(run_time) AS t, ci, ci_harmonic FROM runs "
                    "ORDER BY 1, 2").fetchnumpy()
    con.close()
    ids, t = d["actuator_id"], floats(d["t"])
    ci = judged_ci(floats(d["ci"]), floats(d["ci_harmonic"]))
    err, inside, failed, warned, span = [], [], 0, 0, []
    for a in np.unique(ids):
        m = ids == a
        ta, ya = t[m], ci[m]
        hit = np.flatnonzero(ya < R.FAILURE)
        if not len(hit):
            continue
        failed += 1
        warned += int((ya[:hit[0]] < R.WARNING).any())
        below = np.flatnonzero(ya[:hit[0] + 1] < R.THRESHOLD)
        span.append(hit[0] - below[0])           # tests from the threshold to failure
        for k in range(hit[0]):
            rul, (lo, hi), *_ = rul_of(ta[:k + 1], ya[:k + 1])
            if np.isfinite(rul):
                true = (ta[hit[0]] - ta[k]) / DAY_S
                err.append(rul - true)
                inside.append(lo <= true <= hi)
    return {"rul_failed": failed, "rul_warned_before": warned, "rul_n": len(err),
            "rul_tests_thr_to_fail": float(np.median(span)) if span else float("nan"),
            "rul_med_abs_err_d": float(np.median(np.abs(err))) if err else float("nan"),
            "rul_coverage": float(np.mean(inside)) if inside else float("nan")}


def main() -> None:  # long: the benchmark's stages in order, each timed
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--actuators", type=int, default=30)
    ap.add_argument("--days", type=int, default=20)
    ap.add_argument("--scaling-logs", type=int, default=120,
                    help="logs ingested on 1 and on 2 workers for the speed-up")
    ap.add_argument("--status-runs", type=int, default=10_000)
    ap.add_argument("--dir", default=None, help="work directory (default: a temporary one)")
    ap.add_argument("--write", metavar="PATH", help="update the Fleet section of this file")
    ap.add_argument("--json", metavar="PATH")
    ap.add_argument("--cost-only", metavar="LOGDIR", help="only the warm per-log ingest "
                    "cost in this process, over 44 logs of LOGDIR")
    ap.add_argument("--from-json", metavar="PATH", help="write the section of an earlier "
                    "run's JSON (with --write) instead of running")
    ap.add_argument("--before", metavar="PATH", help="JSON of earlier --cost-only runs to "
                    "quote in the section: {label: {cpu_per_log_s, wall_per_log_s, "
                    "cpu_load}}")
    a = ap.parse_args()
    if a.cost_only:
        print(json.dumps({**ingest_cost(Path(a.cost_only)), **synth_cost()}))
        return
    if a.from_json:
        res = json.loads(Path(a.from_json).read_text())
        if a.write:
            write_section(a.write, section(res))
        return
    work = Path(a.dir or tempfile.mkdtemp(prefix="bench-fleet-"))
    work.mkdir(parents=True, exist_ok=True)
    logs, db = work / "logs", work / "fleet.duckdb"
    n_logs = a.actuators * a.days
    from bench.fleet.ingest import chunk_size
    res: dict[str, Any] = {"actuators": a.actuators, "days": a.days, "logs": n_logs}
    load0 = os.getloadavg()[0]
    t_synth, rss_synth, _ = run(["synth", "--actuators", str(a.actuators), "--days",
                                 str(a.days), "--out", str(logs), "--seed", "1",
                                 "--workers", "2"])
    res.update(synth_s=t_synth, synth_rss=rss_synth)
    print(f"synth {n_logs} logs: {t_synth:.1f} s, peak {rss_synth / 2**20:.0f} MiB", flush=True)
    files = sorted(logs.rglob("*.log"))[:a.scaling_logs]
    sub = work / "scaling"
    sub.mkdir(exist_ok=True)
    for f in files:
        (sub / f"{f.parent.name}_{f.name}").symlink_to(f)
    for w in (1, 2):
        sdb = work / f"scaling-{w}.duckdb"
        sdb.unlink(missing_ok=True)
        t, rss, _ = run(["ingest", str(sub), "--db", str(sdb), "--workers", str(w),
                         "--actuator", "scaling"])
        res[f"ingest{w}_s"], res[f"ingest{w}_rss"] = t, rss
        print(f"ingest {len(files)} logs on {w} worker(s): {t:.1f} s "
              f"({len(files) / t:.2f} logs/s), peak {rss / 2**20:.0f} MiB", flush=True)
    res["scaling_logs"] = len(files)
    res["chunk_note"] = (f"{chunk_size(len(files), 2)} per Dask task for the {len(files)}, "
                         f"{chunk_size(n_logs, 2)} for the {n_logs}")
    db.unlink(missing_ok=True)
    t_ing, rss_ing, _ = run(["ingest", str(logs), "--db", str(db), "--workers", "2"])
    res.update(ingest_s=t_ing, ingest_rss=rss_ing)
    print(f"ingest {n_logs} logs on 2 workers: {t_ing:.1f} s, peak "
          f"{rss_ing / 2**20:.0f} MiB", flush=True)
    t_again, _, _ = run(["ingest", str(logs), "--db", str(db), "--workers", "2"])
    res["reingest_s"] = t_again
    t_stat, _, out = run(["status", "--db", str(db)])
    res["status_s"] = t_stat
    big = work / "big.duckdb"
    res["status_runs"] = grow_store(db, big, a.status_runs)
    t_big, _, _ = run(["status", "--db", str(big)])
    res["status_big_s"], res["big_db_bytes"] = t_big, big.stat().st_size
    exp = work / "export"
    run(["export", "--db", str(db), "--out", str(exp)])
    res["db_bytes"] = db.stat().st_size
    res["parquet_runs_bytes"] = (exp / "runs.parquet").stat().st_size
    res["log_bytes"] = sum(f.stat().st_size for f in logs.rglob("*.log"))
    res["load_start"], res["load_end"] = load0, os.getloadavg()[0]
    res.update(rul_check(db))
    res.update(ingest_cost(logs))
    res.update(synth_cost())
    if a.before:
        res["before"] = json.loads(Path(a.before).read_text())
    print(json.dumps(res, indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    if a.write:
        write_section(a.write, section(res))


def section(r: dict) -> str:  # type: ignore[type-arg]
    n = r["logs"]
    s1, s2 = r["scaling_logs"] / r["ingest1_s"], r["scaling_logs"] / r["ingest2_s"]
    e2e = r["synth_s"] + r["ingest_s"]
    mib = 2 ** 20
    return f"""## Fleet

`python benchmarks/bench_fleet.py --actuators {r['actuators']} --days {r['days']} --write docs/performance.md`
(every stage the real `python -m bench fleet ...` CLI as a subprocess, wall clock, peak
RSS of the process tree; 2 vCPU Xeon shared VM, load average {r['load_start']:.1f} at the
start and {r['load_end']:.1f} at the end{_others(r)}).
A log is one daily ground test: the thesis' 2 Hz sine, 4 periods, 2 s, 12,001 candump
lines, {r['log_bytes'] / n / 1e3:.0f} kB.

| stage | logs | wall (s) | logs/s | peak RSS (MiB) |
|---|---:|---:|---:|---:|
| ingest, 1 worker | {r['scaling_logs']} | {r['ingest1_s']:.1f} | {s1:.2f} | {r['ingest1_rss'] / mib:.0f} |
| ingest, 2 workers | {r['scaling_logs']} | {r['ingest2_s']:.1f} | {s2:.2f} | {r['ingest2_rss'] / mib:.0f} |
| synth, 2 workers | {n} | {r['synth_s']:.1f} | {n / r['synth_s']:.2f} | {r['synth_rss'] / mib:.0f} |
| ingest, 2 workers | {n} | {r['ingest_s']:.1f} | {n / r['ingest_s']:.2f} | {r['ingest_rss'] / mib:.0f} |
| ingest again (all skipped by digest) | {n} | {r['reingest_s']:.1f} | | |
| `fleet status`, {r['actuators']} actuators | {n} runs | {r['status_s']:.2f} | | |
| `fleet status`, {r['status_runs']} runs | {r['status_runs']} runs | {r['status_big_s']:.2f} | | |

Workers: the Dask LocalCluster of `bench.runtime.workers.run_all` (1 worker: in-process), the
logs sent {r.get('chunk_note', 'several per task')}; one BLAS thread per process.
Speed-up of the second worker: {s2 / s1:.2f} x ({s2 / s1 / 2:.2f} per worker). Both
times include the workers' start (spawn, imports, numba compilation, the monitoring
model's gain fit: paid once per worker per ingest, and a LocalCluster's start besides),
which weighs on {r['scaling_logs']} logs of ~{r.get('cpu_per_log_s', 0.0):.2f} s each:
the {n}-log ingest on 2 workers ran at {n / r['ingest_s']:.2f} logs/s,
{n / r['ingest_s'] / s1:.2f} x the 1-worker rate above; on 2 shared cores at this load the
second worker cannot add a full core.{_pool(r)}{_cpu(r)}{_before(r)}
End to end, synth + ingest of {n} logs: {e2e:.0f} s ({n / e2e:.2f} logs/s).
Store: {r['big_db_bytes'] / r['status_runs']:.0f} bytes per run in the DuckDB file of
{r['status_runs']} runs ({r['db_bytes'] / 2**20:.1f} MiB for {n}: DuckDB allocates in
256 kB blocks), {r['parquet_runs_bytes'] / n:.0f} bytes per run as Parquet. {_grown(r)}
{_full(n, e2e)}{_projection(r)}

The fleet RUL checked on this synthetic fleet (the thesis' algorithm and levels as they
are, nothing fitted to it): {r['rul_failed']} actuators reached Ci < 0.56 within the
{r['days']} days, {r['rul_warned_before']} of them with a test below the warning level
0.80 before that; median {r['rul_tests_thr_to_fail']:.0f} daily tests from the first
below the threshold 0.93 to the failure. Re-made after every test from the tests up to
then only, the RUL gave {_rul_numbers(r)} docs/fleet.md checks it against the synthetic
fleet's truth day by day (alpha-lambda, band coverage, notice before the end of life).
"""


def _others(r: dict) -> str:  # type: ignore[type-arg]
    if max(r["load_start"], r["load_end"]) > 3.0:
        return ": other jobs shared the two cores"
    return ": nothing else ran on the machine"


def _grown(r: dict) -> str:  # type: ignore[type-arg]
    if r["status_runs"] <= r["logs"]:
        return (f"The `fleet status` on {r['status_runs']} runs is the measured store "
                "itself.")
    return (f"The `fleet status` on {r['status_runs']} runs reads a store grown from the "
            "measured one by copying its runs under new digests and actuator ids.")


def _rul_numbers(r: dict) -> str:  # type: ignore[type-arg]
    if not r["rul_n"]:
        return "no prediction at all before a failure."
    return (f"{r['rul_n']} predictions; median |predicted - actual| "
            f"{r['rul_med_abs_err_d']:.1f} days, actual failure day inside the 90 % band "
            f"in {100 * r['rul_coverage']:.0f} % of them.")


def _pool(r: dict) -> str:  # type: ignore[type-arg]
    if "pool_ingest1_s" not in r:
        return ""
    n = r["scaling_logs"]
    return (f" The same {n} logs on the home-made process pool this replaced (measured "
            f"earlier in the same session, load 10-15): {r['pool_ingest1_s']:.1f} s on 1 "
            f"worker, {r['pool_ingest2_s']:.1f} s on 2 "
            f"({r['pool_ingest1_s'] / r['pool_ingest2_s']:.2f} x); the synth row also ran on "
            "that pool.")


def _cpu(r: dict) -> str:  # type: ignore[type-arg]
    if "cpu_per_log_s" not in r:
        return ""
    return (f" Per log, warm, in one process: {r['cpu_per_log_s']:.3f} s CPU "
            f"({r['wall_per_log_s']:.2f} s wall at load {r['cpu_load']:.0f}; "
            "`python benchmarks/bench_fleet.py --cost-only`): the figure docs/scale.md "
            "scales with.")


def _before(r: dict) -> str:  # type: ignore[type-arg]
    if "before" not in r:
        return ""
    parts = [f"{label}: {v['cpu_per_log_s']:.3f} s CPU ({v['wall_per_log_s']:.3f} s wall, "
             f"load {v['cpu_load']:.1f})" for label, v in r["before"].items()]
    return " The same `--cost-only` measurement, per log: " + "; ".join(parts) + "."


def _projection(r: dict) -> str:  # type: ignore[type-arg]
    if "synth_cpu_per_log_s" not in r or "cpu_per_log_s" not in r:
        return ""
    cpu = r["synth_cpu_per_log_s"] + r["cpu_per_log_s"]
    return (f" On two cores of their own, the CPU per log (synth {r['synth_cpu_per_log_s']:.3f}"
            f" s, of which write_candump {r['write_cpu_per_log_s']:.4f} s; ingest "
            f"{r['cpu_per_log_s']:.3f} s) gives 10,000 x {cpu:.3f} s / 2 = "
            f"{10_000 * cpu / 2 / 60:.0f} min end to end, plus the workers' start and the "
            "parent's digests and writes (a projection, not a measurement).")


def _full(n: int, e2e: float) -> str:
    if n >= 10_000:
        return f"The {n} logs are the full run, measured: {e2e / 60:.1f} min."
    return (f"10,000 logs end to end was **not run**: at the rate above it is an "
            f"extrapolation, {10_000 / (n / e2e) / 60:.0f} min on this machine in this "
            "load; the command for the full run is "
            "`python benchmarks/bench_fleet.py --actuators 100 --days 100`.")


if __name__ == "__main__":
    main()
