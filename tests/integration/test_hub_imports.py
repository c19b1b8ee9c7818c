"""The loopback hub's process refuses python-can's MF4 import (asammdf, ~0.6 s of start-up;
the hub writes no log); every other process keeps it (`bench log --format mf4`)."""

from __future__ import annotations

import subprocess
import sys

from bench.bus import HUB_MODULE, started_as


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
