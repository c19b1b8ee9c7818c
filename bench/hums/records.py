"""A run's record: the HUMS indexes of every command period, time-stamped at the period's
END (the moment an online monitor has them), with the simulation truth at those times
(never used by the predictors, only to score them).

`simulate_record` runs the RUL sine (the H4 sine, +-0.5 mm, 2 Hz) on the plant with its
degradation schedule (`params.schedule`: preload falling linearly to 0 at
`preload_zero_frac` of the run, backlash and friction growing exponentially, thesis
section 6.5 / figs. 6.11-6.12) and indexes it per period against the monitoring model
(eq. 6.1-6.2; indexes eq. 6.4-6.7). Failure is the thesis' definition: Ci (eq. 6.6)
below 0.56; `true_failure_time` reads it on a noise-free twin run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums import indexes as I
from bench.hums import monitor as M
from bench.hums.rul import FAILURE
from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


@dataclass
class RunRecord:
    """Per-period indexes of one run, time-stamped at period ends, plus simulation truth
    at those times (never used by the predictors, only to score them)."""
    t_s: np.ndarray
    table: dict[str, np.ndarray]
    truth: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def col(self, name: str) -> np.ndarray:
        return self.table[name]


def record_from_trace(real: Any, kp: float, mparams: M.MonitorParams | None = None,
                      period_s: float | None = None) -> RunRecord:
    """Per-period indexes of a trace (measured columns only) against the monitor."""
    meas = real.measured()
    nom = M.nominal_for(meas, kp, mparams)
    rows = list(I.period_indexes(meas, nom, period_s))
    if not rows:
        raise BenchError("the trace is shorter than one command period")
    tab = I.as_table(rows)
    per = rows[0].t_end_s - rows[0].t_start_s
    t_end = tab["t_start_s"] + per
    truth: dict[str, np.ndarray] = {}
    idx = np.clip(np.searchsorted(real.t, t_end) - 1, 0, len(real) - 1)
    for k in ("backlash_m", "friction_scale", "preload_n"):
        if k in real:
            truth[k] = real[k][idx]
    return RunRecord(t_end, tab, truth, {"period_s": per,
                                         "duration_s": float(real.t[-1] + real.dt)})


def simulate_record(params: PlantParams, kp: float, duration_s: float | None = None,
                    progress: bool = False) -> RunRecord:
    """Run the RUL sine with `params` (schedule included) and index it per period."""
    dur = duration_s if duration_s is not None else (
        params.schedule.duration_s if params.schedule.kind == "rul" else 120.0)
    prof = make_profile("sine", duration_s=dur)
    real = simulate(prof, params, progress=progress)
    if not real.meta.get("complete", True):
        raise BenchError("the plant stopped integrating (non-finite state) during the run")
    rec = record_from_trace(real, kp, M.MonitorParams.from_plant(params))
    rec.meta["params"] = params.to_json()
    return rec


def true_failure_time(t: np.ndarray, ci: np.ndarray, failure: float = FAILURE) -> float:
    """End time of the first period with Ci below `failure` (NaN if never)."""
    hit = np.flatnonzero(np.asarray(ci) < failure)
    return float(t[hit[0]]) if len(hit) else math.nan
