"""The verdict of a stretch of a run against the thesis' monitoring model (a
`bench.core.verdict.Verdict`: HEALTHY / DEGRADED / WARNING / FAILURE / UNKNOWN) from its
indexes, the ECU's mode and (long logs) the fused backlash estimate. One function,
`judge`, for the HUMS report (`bench.hums.report.verdict`, a whole log) and the live
watcher (`bench.hums.live`, one command period).

The Ci it judges is `judged_ci`, the one place that picks it: Ci on the command frequency
and its first 15 harmonics where the window has a command frequency, else the broadband
Ci (eq. 6.6 over the whole spectrum). Every output that prints "Ci" (report, CLI,
watcher, demo, fleet status) prints this one; the broadband value is "Ci broadband".
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np

from bench.core.verdict import Level, Verdict
from bench.hums.indexes import Indexes
from bench.signals.trace import MODE_POSITION, MODE_SPEED

THESIS_MODEL = "thesis model"
"""The reference of every `judge` verdict: the thesis' monitoring model and its levels."""


@overload
def judged_ci(ci_broadband: float, ci_harmonic: float) -> float: ...
@overload
def judged_ci(ci_broadband: np.ndarray, ci_harmonic: np.ndarray) -> np.ndarray: ...
def judged_ci(ci_broadband: Any, ci_harmonic: Any) -> Any:
    """The Ci the verdict reads, the thesis' levels 0.93 / 0.80 / 0.56 apply to and every
    output calls "Ci": the harmonic reading (eq. 6.6 restricted to the command frequency
    and its first 15 multiples, `bench.hums.formulas.ci_harmonic`) where it is finite,
    else the broadband one (eq. 6.6 over the whole spectrum, `formulas.ci`).

    Why the harmonic one: the thesis' levels were set on its model, where Ci is 1.00 on a
    healthy actuator; broadband sensor and loop noise up to 500 Hz pulls the broadband
    reading of a healthy actuator to 0.907 with the bench's noise (sweep row H6), below the
    0.93 threshold, while the harmonic reading reads 1.006 without noise and 1.008 with it,
    within 0.003 of the broadband one without noise (1.006 / 1.004 at 0 %, 0.544 / 0.541
    at 100 %: harmonic / broadband).
    Scalars give a float, arrays an array (element by element)."""
    h = np.asarray(ci_harmonic, dtype=float)
    b = np.asarray(ci_broadband, dtype=float)
    out = np.where(np.isfinite(h), h, b)
    return float(out) if out.ndim == 0 else out


def index_record(ix: Indexes) -> dict[str, Any]:
    """The indexes of `ix` under the names every output uses: ``ci`` the judged Ci
    (`judged_ci`), ``ci_broadband`` eq. 6.6 over the whole spectrum, ``ci_harmonic`` the
    15-harmonic reading (NaN without a command frequency), the others as `Indexes.to_json`."""
    d = ix.to_json()
    d["ci_broadband"] = d.pop("ci")
    d["ci"] = judged_ci(ix.ci, ix.ci_harmonic)
    return d


def judge(ix: Indexes, mode: int, fused: Any = None) -> Verdict:
    """HEALTHY / DEGRADED / WARNING / FAILURE with the index that set it (the effect:
    "Ci", "Cp", "fused backlash", "lost motion"; "none" when HEALTHY) and the reasons,
    from the thesis' Ci levels (0.93 / 0.80 / 0.56) in position mode, Cp in speed mode,
    and the fused backlash estimate (`fused`: (FusedResult, Calibration, t_end) or None)
    against its warning level, else the lost motion; UNKNOWN (first reason: what is
    missing) when nothing was commanded (`mode` neither position nor speed) or the index
    the mode's level rests on is not available. Judged against `THESIS_MODEL`."""
    reasons: list[str] = []
    ci = judged_ci(ix.ci, ix.ci_harmonic)
    if mode not in (MODE_POSITION, MODE_SPEED):
        return Verdict.unknown(["the ECU is idle (mode 0) through the log: nothing was "
                                "commanded, so there is no index to judge"], THESIS_MODEL)
    key, value = ("Ci", ci) if mode == MODE_POSITION else ("Cp", ix.cp)
    unknown = None
    if not math.isfinite(value):
        why = ix.unavailable.get(key.lower()) or "not available (not computable from this log)"
        unknown = f"{key} {why}"
    level, effect = Level.HEALTHY, "none"
    if math.isfinite(ci) and mode == MODE_POSITION:
        level, effect = _ci_level(ci, reasons), "Ci"
    if math.isfinite(ix.cp) and mode == MODE_SPEED:
        level, effect = _cp_level(ix.cp, reasons), "Cp"
    rest = _backlash_level(ix, fused, reasons)
    if rest > level:
        level, effect = rest, "fused backlash" if fused is not None else "lost motion"
    if unknown is not None:
        return Verdict.unknown([unknown] + reasons, THESIS_MODEL)
    return Verdict(level, effect if level > Level.HEALTHY else "none", tuple(reasons),
                   THESIS_MODEL)


def _ci_level(ci: float, reasons: list[str]) -> Level:
    """The thesis' Ci levels (section 6.5): failure, warning, threshold (DEGRADED)."""
    from bench.hums import rul as R
    if ci < R.FAILURE:
        reasons.append(f"Ci = {ci:.3f} is below the failure level {R.FAILURE}")
        return Level.FAILURE
    if ci < R.WARNING:
        reasons.append(f"Ci = {ci:.3f} is below the warning level {R.WARNING}")
        return Level.WARNING
    if ci < R.THRESHOLD:
        reasons.append(f"Ci = {ci:.3f} is below the threshold {R.THRESHOLD} "
                       "(deviation from nominal no longer negligible)")
        return Level.DEGRADED
    reasons.append(f"Ci = {ci:.3f} is within 7 % of nominal")
    return Level.HEALTHY


def _cp_level(cp: float, reasons: list[str]) -> Level:
    if cp > 1.005:     # 4x the largest noise effect on Cp in the sweep (H6)
        reasons.append(f"Cp = {cp:.3f}: the nut moves {100 * (1 - 1 / cp):.1f} % "
                       "less than nominal (lost motion)")
        return Level.DEGRADED
    reasons.append(f"Cp = {cp:.4f} is within 0.5 % of nominal")
    return Level.HEALTHY


def _backlash_level(ix: Indexes, fused: Any, reasons: list[str]) -> Level:
    """The fused backlash estimate (the median of its last three periods) on the Ci
    levels' scale, else the lost motion: FAILURE from the backlash at which the
    calibration sweep's Ci reaches 0.56, WARNING from where it reaches 0.80, DEGRADED once
    the estimate has crossed its detection level (measurably above every healthy
    calibration run: the fused predictor's warning, from which the RUL is predicted)."""
    if fused is not None:
        return _fused_level(fused, reasons)
    if math.isfinite(ix.lost_motion_m):
        lm = ix.lost_motion_m * 1e6
        if lm > 5.0:
            reasons.append(f"lost motion between motor and nut {lm:.1f} um (nominal "
                           f"{ix.nominal_lost_motion_m * 1e6:.1f} um)")
            return Level.DEGRADED
    return Level.HEALTHY


def _fused_level(fused: Any, reasons: list[str]) -> Level:
    from bench.hums import rul as R
    fr, cal, _ = fused
    b = float(np.nanmedian(fr.b_um[-3:]))
    levels = ((Level.FAILURE, "failure", cal.fail_um, R.FAILURE),
              (Level.WARNING, "warning", cal.backlash_at_ci(R.WARNING), R.WARNING))
    for level, name, b_lv, ci_lv in levels:
        if b >= b_lv:
            reasons.append(f"fused backlash estimate {b:.1f} um is above the {name} backlash "
                           f"{b_lv:.1f} um (where the calibration sweep's Ci reaches {ci_lv})")
            return level
    if math.isfinite(fr.t_warning_s):
        reasons.append(f"fused backlash estimate {b:.1f} um: backlash detected (above the "
                       f"detection level {cal.warn_um:.2f} um since t = {fr.t_warning_s:.1f}"
                       f" s), below the warning backlash {levels[1][2]:.1f} um")
        return Level.DEGRADED
    reasons.append(f"fused backlash estimate {b:.2f} um is below the detection level "
                   f"{cal.warn_um:.2f} um")
    return Level.HEALTHY
