"""The loopback hub's process refuses python-can's MF4 import (asammdf, ~0.6 s of start-up;
the hub writes no log); so does every `bench` command's own process until it opens an MF4
log; a plain import keeps it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from bench.bus import HUB_MODULE, started_as

HELPERS = Path(__file__).resolve().parents[1] / "unit"


def _imported(args: list[str]) -> set[str]:
    err = subprocess.run([sys.executable, "-X", "importtime", *args], capture_output=True,
                         text=True, timeout=60).stderr
    return {line.rsplit("|", 1)[1].strip() for line in err.splitlines()
            if line.startswith("import time:") and "|" in line}


def test_started_as_reads_the_original_command_line():
    assert started_as(HUB_MODULE, ["python", "-X", "importtime", "-m", HUB_MODULE, "--help"])
    assert started_as(HUB_MODULE, ["python", f"-m{HUB_MODULE}"])
    assert not started_as(HUB_MODULE, ["python", "-c", "import bench.bus.hub"])
    assert not started_as(HUB_MODULE, ["bench", "up"])


def test_the_hub_process_does_not_load_asammdf_and_others_do():
    hub = _imported(["-m", HUB_MODULE, "--help"])
    assert "can" in hub and "asammdf.blocks" not in hub and "pandas" not in hub
    other = _imported(["-c", "import bench.bus.hub"])
    assert "asammdf.blocks" in other          # python-can's MF4 support stays elsewhere


MF4_ROUND_TRIP = """
import sys
from bench.cli import main
sys.argv = ["bench", "decode", {log!r}]
assert main() == 0                                  # a candump log: no MF4 support loaded
assert sys.modules.get("asammdf", 0) is None, "asammdf loaded for a candump log"
from bench.bus.logs import read_frames
from bench.bus.logwrite import open_writer
sys.path.insert(0, {helpers!r})
from log_frames import run
writer = open_writer({mf4!r})                       # an MF4 log: asammdf loaded on demand
for msg in run(30):
    writer.on_message_received(msg)
writer.stop()
assert sys.modules["asammdf"] is not None
print(sum(1 for _ in read_frames({mf4!r})), "frames")
"""


def test_a_bench_process_loads_mf4_support_only_for_an_mf4_log(tmp_path):
    """A `bench` command run as its own process refuses python-can's MF4 import (asammdf,
    pandas, sympy: 0.6-2 s of CPU at every command's start-up) and loads it when it opens
    an MF4 log: `bench decode` of a candump log imports no asammdf, and the same process
    then writes an .mf4 log and reads it back (python-can's MF4 writer and reader raised
    NotImplementedError while asammdf was refused)."""
    sys.path.insert(0, str(HELPERS))
    from log_frames import run, write_log
    log, mf4 = tmp_path / "run.log", tmp_path / "run.mf4"
    write_log(str(log), run(30))
    code = MF4_ROUND_TRIP.format(helpers=str(HELPERS), log=str(log), mf4=str(mf4))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120, env={**os.environ,
                                         "BENCH_STATE_DIR": str(tmp_path / "state")})
    assert r.returncode == 0, r.stderr
    n = sum(1 for line in log.read_text().splitlines() if line.strip())
    assert r.stdout.strip().splitlines()[-1] == f"{n} frames", r.stdout
