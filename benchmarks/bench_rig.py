"""Real-rig benchmark: one cycle's verdict, and `bench rig study` of about 1000 cycles,
this tree beside another (an older commit's worktree) in one run.

    python benchmarks/bench_rig.py --data CRANFIELD_DIR [--old TREE] [--write DOC]

CRANFIELD_DIR holds the Cranfield development set's tables (docs/real-data.md says where
the data set comes from; the repository does not ship it). TREE is a checkout of the
code to compare with (e.g. `git worktree add /tmp/old COMMIT`); each tree runs in its
own processes (PYTHONPATH=tree), one after the other, never at the same time.

1. One cycle's verdict: its features against its load's baseline and the verdict
   (`features.cycle_features` + `features.rig_verdict`), in one process, over every
   cycle of the development set that did not build the baseline (the baseline and
   thresholds of healthy runs 1-4; healthy runs 5-6 and every fault table: 1375 cycles),
   each judged once, as a new cycle is (nothing of it computed before). Goal: < 5 ms.
2. The study of about 1000 cycles: `bench rig study` in a fresh process on 2 worker
   processes (`--workers 2`), calibrated on healthy runs 1-4 and held out 5-6, over the
   healthy tables, backlash1, lackLubrication1 and spalling stages 1, 3, 5, 7 and 8 (925
   cycles): baseline, thresholds, every cycle scored, the cross-validation over the 15
   choices of 4 calibration runs (every fault cycle judged under each), the
   leave-runs-out validation of the classifiers, report and figures. Goal: < 2 min.

The ratios are old / new (above 1: this tree is faster). The machine's 1-minute load
average is printed before and after: on a shared machine the wall times are an upper
bound, and only the side-by-side ratio compares the trees.

`--write` replaces the "## Real rigs (bench rig)" section of the given file.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
from perfdoc import publish  # noqa: E402

SECTION = "## Real rigs (bench rig)"
SUBSET = ("normal_runs1-4", "normal_runs5-6", "backlash1_runs1-5",
          "lackLubrication1_runs1-5", "spalling1", "spalling3", "spalling5", "spalling7",
          "spalling8")

# run in a fresh interpreter with PYTHONPATH=<tree>: only the API both trees share
VERDICT_CODE = r"""
import json, sys, time
from pathlib import Path
import numpy as np
from bench.rig import update as U
from bench.rig.cycles import read_cycles
from bench.rig.features import cycle_features, rig_verdict
data = Path(sys.argv[1])
healthy = [c for f in sorted(data.glob("normal*.csv.xz")) for c in read_cycles(f)]
base, _ = U.build([c for c in healthy if c.run <= 4], ["normal"], 5.0, "kgf", 0.05)
cycles = [c for c in healthy if c.run > 4]
cycles += [c for f in sorted(data.glob("*.csv.xz")) if not f.name.startswith("normal")
           for c in read_cycles(f)]
warm = read_cycles(data / "normal_runs5-6.csv.xz")[0]      # imports, compiled code loaded
rig_verdict(base, cycle_features(base.for_load(warm.load), warm, 5.0),
            base.thresholds[f"{warm.load:g}"]["thresholds"])
times = []
for c in cycles:
    thr = base.thresholds[f"{c.load:g}"]["thresholds"]
    t0 = time.perf_counter()
    rig_verdict(base, cycle_features(base.for_load(c.load), c, 5.0), thr)
    times.append(time.perf_counter() - t0)
t = np.asarray(times) * 1e3
print(json.dumps({"cycles": len(t), "median_ms": float(np.median(t)),
                  "p95_ms": float(np.percentile(t, 95)), "max_ms": float(t.max())}))
"""


def _env(tree: Path) -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(tree))


def verdict_times(tree: Path, data: Path) -> dict[str, float]:
    """Per-cycle verdict times of `tree`'s code (a fresh process)."""
    r = subprocess.run([sys.executable, "-c", VERDICT_CODE, str(data)], env=_env(tree),
                       cwd=str(tree), check=True, capture_output=True, text=True)
    return json.loads(r.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def study_time(tree: Path, data: Path, names: tuple[str, ...] | None) -> tuple[float, int]:
    """Wall time of `bench rig study` of `tree` in a fresh process, and the cycles it
    scored."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "tables"
        src.mkdir()
        for f in sorted(data.glob("*.csv.xz")):
            if names is None or f.name[:-len(".csv.xz")] in names:
                os.symlink(f.resolve(), src / f.name)
        cmd = [sys.executable, "-m", "bench", "rig", "study", str(src), "--calibrate-runs",
               "1-4", "--holdout-runs", "5,6", "--actuator", "cranfield", "--workers", "2",
               "--out", str(Path(tmp) / "out")]
        env = dict(_env(tree), BENCH_STATE_DIR=str(Path(tmp) / "state"))
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, cwd=str(tree), check=True, capture_output=True,
                       text=True)
        wall = time.perf_counter() - t0
        sm = json.loads((Path(tmp) / "out" / "study.json").read_text())
    return wall, sum(sm["cost"]["cycles_per_condition"].values())


def _load() -> float:
    return os.getloadavg()[0]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, type=Path, help="the Cranfield tables' folder")
    ap.add_argument("--old", type=Path, help="a checkout of the code to compare with")
    ap.add_argument("--write", metavar="DOC", help="replace the section in this file")
    ap.add_argument("--verdict-only", action="store_true",
                    help="time the verdicts only (print them, write nothing)")
    args = ap.parse_args()
    trees = {"new": ROOT} | ({"old": args.old.resolve()} if args.old else {})
    load0 = _load()
    v = {k: verdict_times(t, args.data) for k, t in trees.items()}
    if args.verdict_only:
        print(json.dumps({"load": [load0, _load()], **v}))
        return 0
    s = {k: study_time(t, args.data, SUBSET) for k, t in trees.items()}
    load1 = _load()
    n = s["new"][1]

    def cells(new: float, old: float | None, fmt: str) -> str:
        if old is None:
            return f"{fmt.format(new)} |"
        return f"{fmt.format(old)} | {fmt.format(new)} | {old / new:.1f}x |"

    old = "old" in trees
    head = ("| job | old | new | old / new | goal | met |" if old
            else "| job | time | goal | met |")
    rule = "|---|---|---|---|---|---|" if old else "|---|---|---|---|"
    vo = v.get("old")
    rows = [f"| one cycle's features and verdict, {k} of {v['new']['cycles']} cycles | "
            f"{cells(v['new'][key], vo[key] if vo else None, '{:.2f} ms')} {goal}"
            for k, key, goal in (
                ("median", "median_ms", f"< 5 ms | {'yes' if v['new']['median_ms'] < 5 else 'no'} |"),
                ("95th percentile", "p95_ms", "- | - |"), ("largest", "max_ms", "- | - |"))]
    rows.append(f"| `bench rig study` of {n} cycles (healthy runs, backlash1, "
                f"lackLubrication1, spalling 1, 3, 5, 7, 8), 2 workers | "
                f"{cells(s['new'][0], s['old'][0] if old else None, '{:.0f} s')} < 2 min | "
                f"{'yes' if s['new'][0] < 120 else 'no'} |")
    cmd = "python benchmarks/bench_rig.py --data CRANFIELD_DIR" + (
        " --old OLD_TREE" if old else "") + (f" --write {args.write}" if args.write else "")
    ratios = ", the ratios compare the trees measured one after the other" if old else ""
    text = "\n".join([
        SECTION, "",
        f"Measured by `{cmd}` on {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; 1-minute load average {load0:.1f} at the start and "
        f"{load1:.1f} at the end (the machine is shared: the wall times are an upper "
        f"bound{ratios})" + (f"; old: {args.old}" if old else "") + ".", "",
        head, rule, *rows, "",
        "A cycle's verdict is timed on each cycle the first time it is judged (its "
        "phases, ramps and phase indexes computed then too). The study's wall time "
        "includes the interpreter's start-up, reading the tables, the two Dask workers' "
        "start, the cross-validation over the 15 choices of 4 calibration runs (each "
        "fault cycle judged under every one) and the leave-runs-out validation of the "
        "classifiers (5 folds).", ""])
    publish(text, args.write)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
