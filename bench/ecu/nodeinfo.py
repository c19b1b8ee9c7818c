"""What the ECU found on the node beyond CiA 301 (the trace's ``meta["node"]``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class NodeInfo:
    """What `Ecu.prepare` found on the node beyond CiA 301 (the trace's ``meta["node"]``)."""
    identity: dict[str, int] = field(default_factory=dict)   # 0x1000, 0x1018 sub 1-4
    missing: list[str] = field(default_factory=list)     # optional objects the node lacks
    params_complete: bool = True       # every 0x2000-0x2008 parameter was read back
    params: dict[str, Any] = field(default_factory=dict)     # those read (node's values)
    encoder_counts_per_rev: int = 0
    encoder_counts_source: str = ""
    sync_period_s: float = 0.0
    sync_period_source: str = ""
    notes: list[str] = field(default_factory=list)       # what the ECU did about it
