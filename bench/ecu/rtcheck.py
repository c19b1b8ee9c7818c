"""A short calibration of real time before a real-time run: what the machine gives now.

A real-time run keeps its deadlines only when the ECU's pacer releases each SYNC on
time and the plant's TPDO set comes back within the TPDO window (80 % of a period).
On a loaded machine neither holds, and the run then goes on the previous values for
whole bursts of periods: its log has missing samples, which the HUMS bridges only up to
5 in a row. So before a real-time run the ECU measures, in 0.2 s:

- its pacer with a period's work (the controller's step, a frame encoded) for
  `CALIBRATION_S`: periods whose work ended after the next release (overruns) and the
  release lateness;
- the round trip of an SDO read of the device type (0x1000, every CiA 301 node has it):
  the same path as SYNC -> TPDO set (ECU, bus, node, bus, ECU).

It says the result at the start, as a warning when real time will not be held (more
than `MAX_OVERRUN_SHARE` of the periods overran, or the round trip's 90th percentile is
beyond the TPDO window), so that the run's gaps are not a surprise. The run still goes
on: it is what real time gives on this machine now, and its gaps are counted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.sim.control import MODE_IDLE, Controller, ControllerParams
from plant_rt.pacing import RealtimePacer

CALIBRATION_S = 0.2
SDO_PROBES = 10
MAX_OVERRUN_SHARE = 0.01
TPDO_WINDOW = 0.8        # of a period: how long the ECU waits for a TPDO set


@dataclass
class RealtimeCheck:
    """What the calibration measured (also in the trace's ``meta["realtime_check"]``)."""
    period_ms: float
    window_ms: float
    periods: int
    overruns: int
    late_p99_us: float
    late_max_us: float
    sdo_round_trip_p50_ms: float
    sdo_round_trip_p90_ms: float
    held: bool

    def message(self) -> str:
        what = (f"in a {self.periods * self.period_ms / 1e3:g} s calibration the ECU's pacer "
                f"overran {self.overruns} of {self.periods} periods (release lateness p99 "
                f"{self.late_p99_us:.0f} us, max {self.late_max_us:.0f} us, period "
                f"{self.period_ms:g} ms) and an SDO round trip took "
                f"{self.sdo_round_trip_p50_ms:.2f} / {self.sdo_round_trip_p90_ms:.2f} ms "
                f"(p50 / p90) against the TPDO window of {self.window_ms:g} ms")
        if self.held:
            return f"real time: {what}"
        return (f"warning: real time will not be held now: {what}; expect late TPDO sets "
                "and missing samples (the HUMS bridges at most 5 in a row). --pace sync "
                "runs in lockstep, exact on any load; --rt-priority N helps where permitted")


def realtime_check(ecu: Any, period_s: float, spin_us: int,
                   seconds: float = CALIBRATION_S) -> RealtimeCheck:
    """Calibrate real time on the ECU `ecu` (a `bench.ecu.master.Ecu`, set up: listening,
    its heartbeat running) for a run of SYNC period `period_s`."""
    rtt = []
    for _ in range(SDO_PROBES):
        t0 = time.perf_counter()
        ecu.sdo_transfer(lambda: ecu.remote.sdo.upload(0x1000, 0))
        rtt.append(time.perf_counter() - t0)
    ctrl = Controller(ControllerParams(sample_period_s=period_s))
    rpdo = ecu.frames.by_name["EMA_RPDO1"]
    pacer = RealtimePacer(period_s, spin_us * 1e-6)
    n = max(20, int(round(seconds / period_s)))
    pacer.start(period_s)
    for _ in range(n):
        pacer.wait()
        demand = ctrl.step(0.0, 0.0, MODE_IDLE, 0.0, 0.0)
        rpdo.encode({"CurrentDemand": demand, "ControlWord": 0}, strict=True)
        pacer.done()
    window_s = TPDO_WINDOW * period_s
    p90 = float(np.percentile(rtt, 90))
    held = pacer.misses <= MAX_OVERRUN_SHARE * n and p90 <= window_s
    return RealtimeCheck(period_ms=period_s * 1e3, window_ms=round(window_s * 1e3, 3),
                         periods=n, overruns=pacer.misses,
                         late_p99_us=pacer.lateness.percentile_us(99),
                         late_max_us=pacer.lateness.max_us,
                         sdo_round_trip_p50_ms=float(np.percentile(rtt, 50)) * 1e3,
                         sdo_round_trip_p90_ms=p90 * 1e3, held=held)
