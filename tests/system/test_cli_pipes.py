"""`bench` as a Unix tool in a pipe: a reader that goes away (`bench rig assess ... | head
-1`) ends the command quietly with 141 (as SIGPIPE would), never a traceback or an
`error:` line; light commands (`bench down`) do not load python-can's MF4 support."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "cranfield_sample"


def test_a_closed_pipe_ends_the_command_quietly(tmp_path):
    from bench.cli import main
    base = tmp_path / "base.json"
    assert main(["rig", "baseline", str(SAMPLE / "normal_load40_runs1-4.csv.xz"), "--runs",
                 "1,2", "--lead-mm", "5", "--out", str(base)]) == 0
    proc = subprocess.Popen(
        [sys.executable, "-c", "from bench.cli import main; raise SystemExit(main())", "rig",
         "assess", str(SAMPLE / "spalling5_load40_runs1-2.csv.xz"), "--baseline", str(base)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()                 # the reader is gone before the first line
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 141, err
    assert b"Traceback" not in err and b"error:" not in err and b"Exception" not in err


def test_bench_down_does_not_import_mf4_support(tmp_path):
    env = {"BENCH_STATE_DIR": str(tmp_path / "state"), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-X", "importtime", "-c",
                          "import sys; sys.argv = ['bench', 'down']; "
                          "from bench.cli import main; raise SystemExit(main())"],
                         capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0 and "nothing to stop" in out.stdout + out.stderr
    mods = {line.rsplit("|", 1)[1].strip() for line in out.stderr.splitlines()
            if line.startswith("import time:")}
    assert "can" in mods and "asammdf.blocks" not in mods
