"""`bench.bus.logs` split by job: the names it had stay importable from it, and
the new modules hold no frame layout (as test_dbc checks for logs.py)."""

from __future__ import annotations

import re
from pathlib import Path

import bench.bus.logs as logs

ROOT = Path(__file__).resolve().parents[2]


def test_logs_keeps_its_names():
    for name in ("LogIssue", "LogIssues", "parse_line", "read_log", "report_issues",
                 "SdoTracker", "trace_from_messages", "trace_from_log", "load_trace",
                 "integrity", "time_ordered", "COLUMNS", "SIGNAL_COLUMNS", "ROW_FRAMES",
                 "MAX_LINE", "OUT_OF_ORDER_S", "MAX_LOST_SYNCS"):
        assert hasattr(logs, name), name


def test_no_frame_layout_in_the_split_modules():
    pattern = re.compile(r"struct\.(pack|unpack|Struct)\(")
    for rel in ("bus/logread", "bus/sdo", "bus/rows", "signals/integrity"):
        assert not pattern.search((ROOT / "bench" / f"{rel}.py").read_text()), rel
