"""What each consumer of a log needs: one declaration per path, regime, effect,
index, report section and calibration, and what a given log can therefore support.

A declaration is a tuple of signals; ``"a|b"`` means either one. Consumers built on the
thesis plant's or the monitoring model's re-simulation also need samples at the SYNC
period (`SYNC_RATE`): their models advance one SYNC period per logged sample. The
generic model (`bench.sim.rigmodel`) runs at its own step and is sampled at the log's
instants, so its consumers take any rate.

`availability(trace)` says, per consumer, ``None`` (available) or the reason it is not
(``"not available: needs X"``); `bench import` and `bench calibrate` print it, and a
consumer that cannot run is left out while the rest runs. This module imports neither
numba nor the plant (tests/unit/test_rig_needs.py keeps the declarations equal to the
constants the consumers check).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from bench.hums.formulas import CURRENT_SIGNALS, LOST_MOTION_SIGNALS, POSITION_SIGNALS
from bench.signals.trace import Trace

PLANT_RESIM = ("t_s", "mode", "current_a", "motor_speed_rad_s", "motor_angle_rad",
               "position_m")
"""The thesis plant's closed-loop re-simulation (bench.gap.problem.NEEDED)."""
MONITOR_DRIVE = ("t_s", "setpoint_position_m", "setpoint_speed_rad_s", "mode")
"""The monitoring model's drive (bench.hums.monitor.NOMINAL_DRIVE)."""
SYNC_RATE = "sync"
"""Pseudo-signal: samples at the SYNC period the model runs at."""

NEEDS: dict[str, tuple[str, ...]] = {
    # calibration
    "calibrate: thesis plant": PLANT_RESIM + (SYNC_RATE,),
    "calibrate: generic model, cascade fitted": ("setpoint_position_m", "position_m"),
    "calibrate: generic model, measured current": ("current_a", "position_m"),
    # gap diagnosis on the thesis plant: the re-simulation, the paths, the regimes
    "gap: closed-loop re-simulation": PLANT_RESIM + ("setpoint_position_m|setpoint_speed_rad_s",
                                                     SYNC_RATE),
    "gap path: drive": ("current_demand_a", "current_a", SYNC_RATE),
    "gap path: mechanics": ("current_demand_a", "motor_speed_rad_s", SYNC_RATE),
    "gap path: screw": ("motor_angle_rad", "position_m"),
    "gap path: sensors": ("motor_speed_rad_s", "motor_angle_rad"),
    "gap regimes: reversal, acceleration, cruise, dwell": PLANT_RESIM + (SYNC_RATE,),
    "gap regime: load change": PLANT_RESIM + ("load_force_n|current_demand_a", SYNC_RATE),
    # effects of the thesis plant's diagnosis: its re-simulation plus the signals their
    # signature shows in
    "gap effect: backlash": PLANT_RESIM + (SYNC_RATE,),
    "gap effect: friction, viscous, stribeck, kt, inertia, current_offset":
        PLANT_RESIM + (SYNC_RATE,),
    "gap effect: resistance, thermal_drift": PLANT_RESIM + ("current_demand_a", SYNC_RATE),
    "gap effect: stiffness, preload, lead, lvdt_gain, lvdt_lag, lvdt_offset":
        PLANT_RESIM + (SYNC_RATE,),
    "gap effect: encoder_gain, sensor_delay, log_skew": PLANT_RESIM + (SYNC_RATE,),
    # the gap against a generic calibration (bench.rig.riggap), any rate
    "rig gap: localisation (signal, regime, direction, position)":
        ("setpoint_position_m", "position_m"),
    "rig gap: ranking (friction, force gain, inertia, controller, localised)":
        ("setpoint_position_m", "position_m"),
    "rig gap: current offset; current parts of the ranking":
        ("setpoint_position_m", "position_m", "current_a"),
    "rig HUMS index: Cp, mean error (eq. 6.4-6.5)": ("setpoint_position_m", "position_m"),
    "rig HUMS index: Ci, peak ratio (eq. 6.6-6.7)":
        ("setpoint_position_m", "position_m", "current_a"),
    # HUMS (chapter 6): the monitoring model and each index
    "HUMS: monitoring model": MONITOR_DRIVE + (SYNC_RATE,),
    "HUMS index: Cp, mean error (eq. 6.4-6.5)": POSITION_SIGNALS + MONITOR_DRIVE + (SYNC_RATE,),
    "HUMS index: Ci, peak ratio (eq. 6.6-6.7)": CURRENT_SIGNALS + MONITOR_DRIVE + (SYNC_RATE,),
    "HUMS index: lost motion": LOST_MOTION_SIGNALS,
    "HUMS report: harmonics (eq. 6.3)": CURRENT_SIGNALS + MONITOR_DRIVE + (SYNC_RATE,),
}


def _has(trace: Trace, name: str) -> bool:
    return name in trace and bool(np.isfinite(trace.columns[name]).any())


def missing(trace: Trace, needs: Iterable[str], sync_period_s: float = 1e-3) -> list[str]:
    """What of `needs` the trace lacks (an alternative ``a|b`` as such; the SYNC rate as
    a phrase naming the log's sample period)."""
    out = []
    for n in needs:
        if n == SYNC_RATE:
            dt = trace.dt
            if not (len(trace) > 1 and abs(dt - sync_period_s) <= 0.05 * sync_period_s):
                out.append(f"samples every {sync_period_s * 1e3:g} ms (the log: every "
                           f"{dt * 1e3:.3g} ms)")
        elif not any(_has(trace, a) for a in n.split("|")):
            out.append(n.replace("|", " or "))
    return out


def availability(trace: Trace, sync_period_s: float = 1e-3) -> dict[str, str | None]:
    """Per consumer: None when `trace` supports it, else ``not available: needs ...``."""
    out: dict[str, str | None] = {}
    for name, needs in NEEDS.items():
        lack = missing(trace, needs, sync_period_s)
        out[name] = f"not available: needs {', '.join(lack)}" if lack else None
    return out


def describe(trace: Trace, sync_period_s: float = 1e-3) -> list[str]:
    """One line per consumer: 'available' or the reason."""
    av = availability(trace, sync_period_s)
    width = max(len(k) for k in av)
    return [f"{k:{width}s}  {v or 'available'}" for k, v in av.items()]
