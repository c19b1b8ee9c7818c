"""A Ctrl-C that a library swallows during its import (measured: 0.5 s into `bench log`,
inside python-can's import of its MF4 support) was lost: `bench log` went on recording
until a second Ctrl-C. The loss is emulated deterministically: the command's first call
after its imports sends SIGINT to its own process and swallows the KeyboardInterrupt, as
the library's broad `except` did."""

from __future__ import annotations

import subprocess
import sys

SCRIPT = """
import os, signal, sys, time
import bench.bus.logwrite as lw
from bench.cli import main

real = lw.open_writer

def swallowing(*a, **k):
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)
    except BaseException:       # what the library did
        pass
    return real(*a, **k)

lw.open_writer = swallowing
sys.exit(main(["log", sys.argv[1], "-i", "virtual", "-c", "lost-ctrl-c", "--duration", "30"]))
"""


def test_bench_log_stops_on_a_ctrl_c_an_import_swallowed(tmp_path):
    log = tmp_path / "x.log"
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(log)], capture_output=True,
                       text=True, timeout=25)
    assert r.returncode == 0, r.stderr
    assert "0 frames written" in r.stdout, r.stdout + r.stderr
    assert log.exists()
