"""Real-rig benchmark: one cycle's verdict, and `bench rig study` of about 1000 cycles.

    python benchmarks/bench_rig.py --data CRANFIELD_DIR [--write docs/performance.md]

CRANFIELD_DIR holds the Cranfield development set's tables (docs/real-data.md says where
the data set comes from; the repository does not ship it).

1. One cycle's verdict: its features against its load's baseline and the verdict
   (`features.cycle_features` + `features.rig_verdict`), in this process, over every
   cycle of the fault tables of the study below (the baseline of healthy runs 1-4).
   Goal: < 5 ms.
2. The study of about 1000 cycles: `bench rig study` in a fresh process on 2 worker
   processes (`--workers 2`), calibrated on healthy runs 1-4 and held out 5-6, over the
   healthy tables, backlash1, lackLubrication1 and spalling stages 1, 3, 5, 7 and 8 (985
   cycles): baseline, thresholds, every cycle scored, the cross-validation over the 15
   choices of 4 calibration runs (every fault cycle judged under each), the
   leave-runs-out validation of the classifiers, report and figures. Goal: < 2 min.
   The whole development set (1435 cycles) is measured beside it.

`--write` replaces the "## Real rigs (bench rig)" section of the given file.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from perfdoc import write_section  # noqa: E402

SECTION = "## Real rigs (bench rig)"
SUBSET = ("normal_runs1-4", "normal_runs5-6", "backlash1_runs1-5",
          "lackLubrication1_runs1-5", "spalling1", "spalling3", "spalling5", "spalling7",
          "spalling8")


def verdict_times(data: Path) -> dict[str, float]:
    import numpy as np

    from bench.rig import update as U
    from bench.rig.cycles import read_cycles
    from bench.rig.features import cycle_features, rig_verdict
    healthy = [c for c in read_cycles(data / "normal_runs1-4.csv.xz") if c.run <= 4]
    base, _ = U.build(healthy, ["normal_runs1-4.csv.xz"], 5.0, "kgf", 0.05)
    cycles = [c for name in SUBSET[2:] for c in read_cycles(data / f"{name}.csv.xz")]
    times = []
    for c in cycles:
        thr = base.thresholds[f"{c.load:g}"]["thresholds"]
        t0 = time.perf_counter()
        rig_verdict(base, cycle_features(base.for_load(c.load), c, 5.0), thr)
        times.append(time.perf_counter() - t0)
    t = np.asarray(times) * 1e3
    return {"cycles": len(t), "median_ms": float(np.median(t)),
            "p95_ms": float(np.percentile(t, 95)), "max_ms": float(t.max())}


def study_time(data: Path, names: tuple[str, ...] | None) -> tuple[float, int]:
    """Wall time of `bench rig study` in a fresh process, and the cycles it read."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "tables"
        src.mkdir()
        files = sorted(data.glob("*.csv.xz"))
        for f in files:
            if names is None or f.name[:-len(".csv.xz")] in names:
                os.symlink(f.resolve(), src / f.name)
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        cmd = [sys.executable, "-m", "bench", "rig", "study", str(src), "--calibrate-runs",
               "1-4", "--holdout-runs", "5,6", "--actuator", "cranfield", "--workers", "2",
               "--out", str(Path(tmp) / "out")]
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        import json
        sm = json.loads((Path(tmp) / "out" / "study.json").read_text())
    n = sum(sm["cost"]["cycles_per_condition"].values())
    return wall, n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, type=Path, help="the Cranfield tables' folder")
    ap.add_argument("--write", metavar="DOC", help="replace the section in this file")
    ap.add_argument("--full", action="store_true", help="also the whole set (1435 cycles)")
    args = ap.parse_args()
    v = verdict_times(args.data)
    sub_s, sub_n = study_time(args.data, SUBSET)
    rows = [f"| `bench rig study` of {sub_n} cycles (healthy runs, backlash1, "
            f"lackLubrication1, spalling 1, 3, 5, 7, 8), 2 workers | {sub_s:.0f} s | < 2 min "
            f"| {'yes' if sub_s < 120 else 'no'} |"]
    if args.full:
        full_s, full_n = study_time(args.data, None)
        rows.append(f"| `bench rig study` of the whole development set, {full_n} cycles, "
                    f"2 workers | {full_s:.0f} s | - | - |")
    load = os.getloadavg()[0]
    import platform
    text = "\n".join([
        SECTION, "",
        f"Measured by `python benchmarks/bench_rig.py --data CRANFIELD_DIR --write "
        f"docs/performance.md{' --full' if args.full else ''}` on {platform.machine()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()} (1-minute load "
        f"average at the end {load:.2f}; the machine is shared, so the wall times are an "
        "upper bound).", "",
        "| job | time | goal | met |", "|---|---|---|---|",
        f"| one cycle's features and verdict, median of {v['cycles']} cycles (95th "
        f"percentile {v['p95_ms']:.1f} ms, largest {v['max_ms']:.1f} ms) | "
        f"{v['median_ms']:.2f} ms | < 5 ms | {'yes' if v['median_ms'] < 5 else 'no'} |",
        *rows, "",
        "The study's wall time includes the interpreter's start-up, reading the tables, "
        "the two Dask workers' start, the cross-validation over the 15 choices of 4 "
        "calibration runs (each fault cycle judged under every one) and the leave-runs-out "
        "validation of the classifiers (5 folds, in the calling process).", ""])
    print(text)
    if args.write:
        write_section(args.write, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
