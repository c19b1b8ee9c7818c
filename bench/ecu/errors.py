"""The errors of a bus run and the plant conditions that make one."""

from __future__ import annotations

import signal

from bench import BenchError
from ema_contract.states import StatusWord


class PlantLost(BenchError):
    """The plant stopped answering (no TPDO, no heartbeat)."""


class BusLost(BenchError):
    """The bus connection itself failed."""


class PlantFault(BenchError):
    """The plant reported a condition that changes its behaviour: the run is not valid."""


class ForeignEcu(BenchError):
    """Another ECU (another SYNC, set-point or heartbeat producer) drives the node."""


class LogWriteError(BenchError):
    """The candump log could not be written (disk full, file too large, ...)."""


class Interrupted(BenchError):
    """The run was stopped by a signal (SIGINT, SIGTERM)."""

    def __init__(self, signum: int, where: str = "") -> None:
        self.signum = int(signum)
        super().__init__(f"interrupted by {signal.Signals(signum).name}{where}")


# Plant conditions that change what the plant does with the ECU's demand (docs/bus.md):
# a run that sees one is not a valid run. Status word bit -> EMCY label (dbc value table).
FAILING_BITS: dict[StatusWord, str] = {
    StatusWord.COMMAND_TIMEOUT: "heartbeat_lost",
    StatusWord.PLANT_FAULT: "plant_fault",
    StatusWord.DEMAND_CLAMPED: "demand_invalid",
}
FAILING_TEXT = {
    "heartbeat_lost": "a command timeout (its heartbeat consumer lost the ECU: demand "
                      "forced to 0)",
    "plant_fault": "a plant fault (non-finite state: the plant stopped integrating)",
    "demand_invalid": "an invalid demand (NaN or beyond its current limit: replaced or "
                      "clamped)",
    "pdo_length": "an RPDO of the wrong length (a demand was not applied)",
}
# EMCYs that only report (the plant does the same with the demand): over-current (the
# drive at its current limit, normal in a step), end of stroke and over-temperature (flags
# only: no end stop, no derating), and the all-clear. Any other code fails the run.
REPORTING_EMCY = ("no_error", "overcurrent", "end_of_stroke", "overtemperature")


def _at(k: int, ts: float) -> str:
    return f" at t = {k * ts:.3f} s (SYNC {k})"


def status_names(word: int) -> list[str]:
    return [f.name.lower() for f in StatusWord if f and f.name and int(word) & f]
