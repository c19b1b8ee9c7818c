"""The ECU's trace rows: the frames it sends and receives, in the order they reach its log,
into the one row assembler (`bench.bus.rows.RowAssembler`), so that the trace a bus run
returns is built by the same code as the trace of its decoded log.

Frames are queued as they pass (`append`, on whichever thread logs them: the main thread
during the run, the receive thread during set-up and the run's end) and fed to the
assembler by the main thread (`drain`) once per period, after the period's RPDO is out:
decoding them (~10 us a frame) stays off the path from the TPDOs to the demand."""

from __future__ import annotations

import threading
from typing import Any

import can
import numpy as np

from bench.bus.rows import RowAssembler, trace_columns
from ema_contract.frames import Frames


class RowTap:
    """Frames in log order -> one row per SYNC period (`RowAssembler`, its default sink)."""

    def __init__(self, frames: Frames, sync_max: int) -> None:
        self.assembler = RowAssembler(frames, sync_max)
        self._pending: list[can.Message] = []
        self._lock = threading.Lock()

    def append(self, msg: can.Message) -> None:
        """Queue a frame (called in log order, under the ECU's record lock)."""
        with self._lock:
            self._pending.append(msg)

    def drain(self) -> None:
        """Feed the queued frames to the assembler (main thread only). Time stamps are
        taken at the candump log's resolution (1 us), so that a row's bus time is the one
        the decoded log gives."""
        with self._lock:
            batch, self._pending = self._pending, []
        feed = self.assembler.feed
        for m in batch:
            m.timestamp = round(m.timestamp, 6)
            feed(m)

    def columns(self, period_s: float, counts_per_rev: float,
                periods: int) -> dict[str, np.ndarray]:
        """The trace columns of the first `periods` SYNC periods (all frames drained)."""
        self.drain()
        rows = self.assembler.finish()
        return trace_columns(rows, period_s, counts_per_rev, periods)

    def counts(self) -> dict[str, Any]:
        """What the assembler counted (frames, lost SYNCs, missing frames per kind)."""
        asm = self.assembler
        return {**asm.count, "missing_frames": asm.rows.missing(asm.seen)}
