"""Run the README's bus session as written, in a fresh folder, and check what it gives.

The session is the ```bash block after "A session on the bus" in README.md, taken from
the README itself so that the two cannot drift apart. It runs in bash with `set -e`
(every command must succeed) with the `bench` found on PATH (the environment under
test), then the files the README promises are checked: the log, the live watcher's CSV,
the HUMS report and the gap diagnosis. A background job of the block (the watcher) is
stopped at the end; `bench down` runs whatever happened.

    python .ci/readme_session.py --work DIR
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARK = "A session on the bus"


def session_block(readme: Path) -> str:
    """The shell block of the README's bus session."""
    text = readme.read_text()
    at = text.index(MARK)
    m = re.search(r"```bash\n(.*?)```", text[at:], re.S)
    if m is None:
        raise SystemExit(f"error: no ```bash block after {MARK!r} in {readme}")
    return m.group(1)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", required=True, help="a folder to run the session in (new)")
    ap.add_argument("--timeout", type=float, default=3600.0)
    args = ap.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=False)
    block = session_block(ROOT / "README.md")
    script = ("set -euo pipefail\n" + block
              + "\nfor j in $(jobs -p); do kill $j 2>/dev/null || true; done\n")
    print(block, flush=True)
    try:
        r = subprocess.run(["bash", "-c", script], cwd=work, timeout=args.timeout)
    finally:
        subprocess.run(["bench", "down"], cwd=work, capture_output=True, timeout=120)
    if r.returncode != 0:
        print(f"error: the README's bus session failed (exit {r.returncode})", file=sys.stderr)
        return 1
    missing = [p for p in ("worn.log", "live.csv", "report/report.html", "gap/index.html")
               if not (work / p).is_file() or (work / p).stat().st_size == 0]
    if missing:
        print(f"error: the session did not write {', '.join(missing)}", file=sys.stderr)
        return 1
    with open(work / "live.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        print("error: the live watcher wrote no command period to live.csv", file=sys.stderr)
        return 1
    print(f"README bus session: ok ({len(rows)} command periods watched live; "
          f"{os.path.getsize(work / 'worn.log')} bytes of log)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
