"""The verdict of a stretch of a run: HEALTHY / DEGRADED / WARNING / FAILURE / UNKNOWN
from its indexes, the ECU's mode and (long logs) the fused backlash estimate. One
function, `judge`, for the HUMS report (`bench.hums.report.verdict`, a whole log) and
the live watcher (`bench.hums.live`, one command period)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.hums.indexes import Indexes
from bench.trace import MODE_POSITION, MODE_SPEED

UNKNOWN = "UNKNOWN"
LEVELS = ["HEALTHY", "DEGRADED", "WARNING", "FAILURE"]


def judge(ix: Indexes, mode: int, fused: Any = None) -> tuple[str, list[str]]:
    """HEALTHY / DEGRADED / WARNING / FAILURE and the reasons, from the thesis' Ci levels
    (0.93 / 0.80 / 0.56) in position mode, Cp in speed mode, and the fused backlash
    estimate (`fused`: (FusedResult, Calibration, t_end) or None) against its warning
    level, else the lost motion; UNKNOWN (first reason: what is missing) when nothing was
    commanded (`mode` neither position nor speed) or the index the mode's level rests on
    is not available."""
    reasons: list[str] = []
    level = 0
    ci = ix.ci_harmonic if math.isfinite(ix.ci_harmonic) else ix.ci
    if mode not in (MODE_POSITION, MODE_SPEED):
        return UNKNOWN, ["the ECU is idle (mode 0) through the log: nothing was commanded, "
                         "so there is no index to judge"]
    key, value = ("Ci", ci) if mode == MODE_POSITION else ("Cp", ix.cp)
    unknown = None
    if not math.isfinite(value):
        why = ix.unavailable.get(key.lower()) or "not available (not computable from this log)"
        unknown = f"{key} {why}"
    if math.isfinite(ci) and mode == MODE_POSITION:
        level = _ci_level(ci, reasons)
    if math.isfinite(ix.cp) and mode == MODE_SPEED:
        level = max(level, _cp_level(ix.cp, reasons))
    level = max(level, _backlash_level(ix, fused, reasons))
    if unknown is not None:
        return UNKNOWN, [unknown] + reasons
    return LEVELS[level], reasons


def _ci_level(ci: float, reasons: list[str]) -> int:
    """The thesis' Ci levels (section 6.5): 3 failure, 2 warning, 1 threshold, else 0."""
    from bench.hums import rul as R
    if ci < R.FAILURE:
        reasons.append(f"Ci = {ci:.3f} is below the failure level {R.FAILURE}")
        return 3
    if ci < R.WARNING:
        reasons.append(f"Ci = {ci:.3f} is below the warning level {R.WARNING}")
        return 2
    if ci < R.THRESHOLD:
        reasons.append(f"Ci = {ci:.3f} is below the threshold {R.THRESHOLD} "
                       "(deviation from nominal no longer negligible)")
        return 1
    reasons.append(f"Ci = {ci:.3f} is within 7 % of nominal")
    return 0


def _cp_level(cp: float, reasons: list[str]) -> int:
    if cp > 1.005:     # 4x the largest noise effect on Cp in the sweep (H6)
        reasons.append(f"Cp = {cp:.3f}: the nut moves {100 * (1 - 1 / cp):.1f} % "
                       "less than nominal (lost motion)")
        return 1
    reasons.append(f"Cp = {cp:.4f} is within 0.5 % of nominal")
    return 0


def _backlash_level(ix: Indexes, fused: Any, reasons: list[str]) -> int:
    """The fused backlash estimate against its warning level, else the lost motion."""
    if fused is not None:
        fr, cal, _ = fused
        b = float(np.nanmedian(fr.b_um[-3:]))
        if math.isfinite(fr.t_warning_s):
            reasons.append(f"fused backlash estimate {b:.1f} um is above the warning level "
                           f"{cal.warn_um:.2f} um (since t = {fr.t_warning_s:.1f} s)")
            return 2
        reasons.append(f"fused backlash estimate {b:.2f} um is below the warning level "
                       f"{cal.warn_um:.2f} um")
        return 0
    if math.isfinite(ix.lost_motion_m):
        lm = ix.lost_motion_m * 1e6
        if lm > 5.0:
            reasons.append(f"lost motion between motor and nut {lm:.1f} um (nominal "
                           f"{ix.nominal_lost_motion_m * 1e6:.1f} um)")
            return 1
    return 0
