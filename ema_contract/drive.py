"""The bus side of an actuator drive written apart from the bench: a CiA 301 node with the
DBC's static PDOs and a fixed SYNC period, on `ema_contract.node.CanopenNode`.

What every such drive does the same way: the heartbeat consumer (0x1016 sub 1) that sets a
command timeout and sends an EMCY, the TPDO1 StatusWord bits (`dbc/ema.dbc` comment), the
error register (0x1001) and SYNC period (0x1006) it reports over SDO, the SDO writes it
refuses (another period, the static PDO parameters 0x1400-0x1BFF), and the process around
`serve()` (signals, ready file, parent watch). What a drive holds, how it latches a demand
and what it samples are the subclass's (`indie_plant.node`, the test double
`tests/integration/minimal_node.py`).
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

from canopen.sdo.exceptions import SdoAbortedError

from ema_contract.node import (
    ABORT_READ_ONLY,
    ABORT_VALUE_RANGE,
    ERR_COMMUNICATION,
    ERR_GENERIC,
    CanopenNode,
)

STATUS_COMMAND_TIMEOUT = 0x10       # TPDO1 StatusWord bits (dbc/ema.dbc comment)
STATUS_DEMAND_CLAMPED = 0x20
STATUS_ENABLED = 0x40


class DriveNode(CanopenNode):
    """A drive's CiA 301 node: `period_s` is its SYNC period (s); `timed_out` is set by the
    heartbeat consumer and cleared by the subclass (a fault reset) or an NMT reset."""

    timed_out = False

    @property
    def period_s(self) -> float:
        raise NotImplementedError

    def consumer_counts(self) -> bool:
        """Whether the heartbeat consumer counts wall time now (default: always)."""
        return True

    def on_timers(self, now: float, nxt: float) -> float:
        """The heartbeat consumer: the ECU lost, demand 0 until a fault reset or NMT reset."""
        timeout_s = self.consumer_timeout_s()
        if timeout_s > 0 and self.ecu_hb is not None and not self.timed_out \
                and now - self.ecu_hb > timeout_s and self.consumer_counts():
            self.timed_out = True
            self.emcy("heartbeat_lost", ERR_GENERIC | ERR_COMMUNICATION)
        return nxt

    def status_word(self, enabled: bool, clamped: bool) -> int:
        """The StatusWord bits of the bus side (enabled, demand clamped, command timeout)."""
        status = (STATUS_ENABLED if enabled else 0) | (STATUS_DEMAND_CLAMPED if clamped else 0)
        return status | (STATUS_COMMAND_TIMEOUT if self.timed_out else 0)

    def emcy(self, label: str, register: int) -> None:
        status = STATUS_COMMAND_TIMEOUT if self.timed_out else 0
        self.send(self.frames.encode("EMA_EMCY", self.emcy_values(label, register, status)))

    def sdo_read(self, index: int, subindex: int, od) -> int | None:  # noqa: ARG002
        if index == 0x1001:
            return ERR_GENERIC | ERR_COMMUNICATION if self.timed_out else 0
        if index == 0x1006:
            return int(round(self.period_s * 1e6))
        return None

    def sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:  # noqa: ARG002
        raw = od.decode_raw(data)
        if index == 0x1006 and raw != int(round(self.period_s * 1e6)):
            raise SdoAbortedError(ABORT_VALUE_RANGE)   # the period is the drive's
        if 0x1400 <= index <= 0x1BFF:
            raise SdoAbortedError(ABORT_READ_ONLY)     # static PDOs: those of the DBC


def serve_process(node: CanopenNode, ready_file: Path | None, parent_pid: int | None,
                  duration_s: float | None) -> None:
    """Serve `node` as its process's whole work: SIGINT and SIGTERM stop it, `ready_file`
    gets the pid before the loop, the loop ends with `parent_pid`'s process or after
    `duration_s`; the node's bus is closed at the end."""
    from ema_contract.transport import close_bus, pid_alive
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *_: node.stop())
    try:
        if ready_file:
            ready_file.write_text(f"{os.getpid()}\n")
        node.serve(duration_s, (lambda: pid_alive(parent_pid)) if parent_pid else None)
    finally:
        close_bus(node.bus)
