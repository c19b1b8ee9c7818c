"""Process start-up benchmark: what the imports of the bench's processes cost.

    python benchmarks/bench_startup.py [--write docs/performance.md] [--repeats 7]

Every process the bench starts pays its imports: the plant node (`python -m plant_rt`),
the loopback hub, the ECU of `bench run`, every `bench` command. Side by side in one run,
interleaved (A, B, A, B, ...) so both see the same load, a fresh interpreter each time:

- the plant node's imports (`plant_rt.node`) as `python -m plant_rt` has them (python-can's
  eager import of asammdf, its MF4 log support, refused: the node writes no log file)
  against the same imports with asammdf loaded (before);
- the ECU's imports (`bench.ecu.master` with `bench.profiles.flight`) without scipy.signal (now:
  imported where a turbulence is drawn) against the same plus `scipy.signal` (before);
- the loopback hub's process as `bench up` starts it (`python -m bench.bus.hub`, asammdf
  refused: the hub writes no log) against the same module run
  under another command line (runpy), which keeps python-can's MF4 import (before);
- `bench down` as the command runs (up, status, down and plant refuse the MF4 import:
  they read and write no log) against the same command called
  in-process (`main(['down'])`, which keeps it: before);
- for scale, `import can` alone with and without asammdf.

Wall time of `python -c "..."` per variant, the median of `--repeats`, and the ratio.
`--write` replaces the "## Start-up" section of the given markdown file.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from perfdoc import publish  # noqa: E402

from bench import machine_description  # noqa: E402

REFUSE = "import sys; sys.modules['asammdf'] = None; "
# `bench down` against a state folder of its own, empty (never the user's running bench)
EMPTY_STATE = ("import os, sys, tempfile; _d = tempfile.TemporaryDirectory(); "
               "os.environ['BENCH_STATE_DIR'] = _d.name; ")
PAIRS = (
    ("plant node imports (`plant_rt.node`)",
     REFUSE + "import plant_rt.node", "import plant_rt.node"),
    ("ECU imports (`bench.ecu.master`, `bench.profiles.flight`)",
     "import bench.ecu.master, bench.profiles.flight",
     "import bench.ecu.master, bench.profiles.flight, scipy.signal"),
    ("loopback hub process (`python -m bench.bus.hub --help`)",
     ["-m", "bench.bus.hub", "--help"],
     "import runpy, sys; sys.argv = ['hub', '--help']; "
     "runpy.run_module('bench.bus.hub', run_name='__main__')"),
    ("`bench down` with nothing to stop",
     EMPTY_STATE + "sys.argv = ['bench', 'down']; from bench.cli import main; main()",
     EMPTY_STATE + "from bench.cli import main; main(['down'])"),
    ("`import can`", REFUSE + "import can", "import can"),
)


def once(code: str | list[str]) -> float:
    """Wall time of a fresh interpreter running `code` (-c) or the argument list."""
    args = code if isinstance(code, list) else ["-c", code]
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], check=True, cwd=ROOT, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def measure(repeats: int) -> list[tuple[str, float, float]]:
    rows = []
    for name, now, before in PAIRS:
        once(now), once(before)                     # warm the file cache
        a, b = [], []
        for _ in range(repeats):
            a.append(once(now))
            b.append(once(before))
        rows.append((name, statistics.median(a), statistics.median(b)))
    return rows


def report(rows: list[tuple[str, float, float]], repeats: int, load: float) -> str:
    lines = ["## Start-up", "",
             f"`python benchmarks/bench_startup.py --repeats {repeats}`: a fresh interpreter "
             "per sample, the two variants interleaved, the median wall time of "
             f"{repeats}. Machine: {machine_description()}; 1-min load average "
             f"{load:.2f} at the start.", "",
             "| imports | now | before | before / now |", "|---|---|---|---|"]
    for name, now, before in rows:
        lines.append(f"| {name} | {now:.2f} s | {before:.2f} s | {before / now:.2f} |")
    lines += ["", "\"Now\" for the plant is what `python -m plant_rt` imports (asammdf "
              "refused), for the ECU what `bench run` imports (scipy.signal deferred to "
              "the flight profile's turbulence), for the hub what `python -m bench.bus.hub` "
              "imports (asammdf refused, its `--help`: imports and argument parsing); "
              "\"before\" is the same with those imports, as it was. `bench up`, `status`, "
              "`down` and `plant` refuse it too (they read and write no log); the other "
              "`bench` commands still load asammdf through python-can (`import can`, last "
              "row): they read or write MF4 logs.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--write", metavar="MD", help="replace this file's start-up section")
    args = ap.parse_args(argv)
    load = os.getloadavg()[0]
    rows = measure(args.repeats)
    text = report(rows, args.repeats, load)
    publish(text, args.write)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
