"""The hub process under 500 readers that never read (item 7: 500 slow readers
held 1.66 GB): with its default limits its memory stays within the queue budget, the
slow readers are dropped and the sender is still served."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from bus_helpers import ROOT

from bench.bus import selecthub as hub_mod

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "unit"))
from test_hub_events import OP_PING, OP_PONG, RawClient, _open  # noqa: E402

SLOW, FRAMES = 500, 2000      # FD frames of 64 bytes: ~460 bytes each as JSON, 0.9 MB/reader


def vm_kib(pid: int, key: str) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    raise KeyError(key)


def test_500_slow_readers_cost_the_hub_at_most_its_queue_budget(tmp_path):
    log = tmp_path / "hub.log"
    with log.open("w") as err:
        hub = subprocess.Popen([sys.executable, "-m", "bench.bus.hub", "--no-state"],
                               cwd=str(ROOT), stdout=subprocess.PIPE, stderr=err, text=True)
    try:
        url = hub.stdout.readline().strip()
        port = int(url.rsplit(":", 1)[1].strip("/"))
        base = vm_kib(hub.pid, "VmRSS")
        for _ in range(SLOW):
            RawClient(port, proto="can.json.v1", rcvbuf=4096)
        tx = RawClient(port)
        t0 = time.monotonic()
        for _ in range(FRAMES):
            tx.send_msg(0x100, bytes(range(64)), flags=0x8)
        tx.send_frame(OP_PING, b"end")
        while tx.recv_frame(timeout=120) != (OP_PONG, b"end"):
            pass
        wall = time.monotonic() - t0
        grew_mib = (vm_kib(hub.pid, "VmHWM") - base) / 1024
        assert hub.poll() is None
        budget_mib = hub_mod.TOTAL_OUTBUF_MAX / 2**20
        # the queues' budget, plus bytearray over-allocation and allocator slack
        assert grew_mib <= 1.5 * budget_mib + 16, (grew_mib, wall)
        assert wall < 60
    finally:
        while _open:
            _open.pop().close()
        hub.terminate()
        hub.wait(10)
        hub.stdout.close()
    dropped = [ln for ln in log.read_text().splitlines() if "dropped client" in ln]
    assert len(dropped) >= hub_mod.LOG_LINES_MAX and all("queue" in ln for ln in dropped)
