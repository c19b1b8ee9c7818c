"""The fleet RUL against the truth: a synthetic fleet (`bench fleet synth`),
ingested (`bench fleet ingest`), then `bench fleet status` evaluated as of the end of
every day (only the tests up to that day) and compared with the truth the HUMS never
saw (`bench.fleet.truthcheck`: RULs before the end of life, alpha-lambda, band
coverage, false alarms, days of notice).

    python benchmarks/bench_fleet_rul.py --actuators 30 --days 40 --seed 1
    python benchmarks/bench_fleet_rul.py --actuators 30 --days 40 --seed 1 --wear time

Synth and ingest run as the real CLI in subprocesses (`nice`), timed on the wall clock
with the load average before and after. Prints the Markdown table of docs/fleet.md;
`--json F` keeps every number (per actuator, per day).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(args: list[str]) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    subprocess.run(["nice", sys.executable, "-m", "bench", *args], check=True, env=env,
                   cwd=ROOT, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--actuators", type=int, default=30)
    ap.add_argument("--days", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--wear", choices=["use", "time"], default="use")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--dir", default=None, help="keep the fleet and store here")
    ap.add_argument("--json", default=None, help="write every number here")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from bench.fleet.truthcheck import check_store, markdown
    work = Path(a.dir or tempfile.mkdtemp(prefix="fleet-rul-"))
    logs, db = work / "logs", work / "fleet.duckdb"
    load0 = os.getloadavg()
    t_synth = _run(["fleet", "synth", "--actuators", str(a.actuators), "--days", str(a.days),
                    "--seed", str(a.seed), "--wear", a.wear, "--out", str(logs),
                    "--workers", str(a.workers)])
    t_ingest = _run(["fleet", "ingest", str(logs), "--db", str(db), "--workers",
                     str(a.workers)])
    t0 = time.perf_counter()
    res = check_store(db, logs / "fleet-truth.json")
    t_check = time.perf_counter() - t0
    load1 = os.getloadavg()
    res["timing"] = {"synth_s": t_synth, "ingest_s": t_ingest, "check_s": t_check,
                     "load_before": load0, "load_after": load1, "workers": a.workers}
    print(markdown(res))
    print(f"\nsynth {t_synth:.1f} s, ingest {t_ingest:.1f} s ({a.workers} workers), check "
          f"{t_check:.2f} s; load average {load0[0]:.2f} before, {load1[0]:.2f} after; "
          f"fleet in {work}")
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
