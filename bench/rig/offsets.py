"""A cycle's position offset in every phase and the sign of its level: what the verdict
reads beside the features (`features.cycle_features`) to name an index `offset` and a
level `drag`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

nan_ = float("nan")


def position_shifts(lb: Any, indexes: dict[str, dict[str, float]]
                    ) -> dict[str, float]:
    """Per phase a cycle (its phase `indexes`) and the baseline share: the cycle's mean
    position error less the baseline's mean of that index, in mm (what the verdict of a
    position-error index reports beside it)."""
    key = "position_error_mean"
    return {phase: vals[key] - lb.indexes[phase][key][0]
            for phase, vals in indexes.items()
            if key in lb.indexes.get(phase, {}) and math.isfinite(vals[key])}


def common_shift(shifts: dict[str, float]) -> bool:
    """True when every phase's mean position error moved the same way by a similar amount
    (the smallest shift at least half the largest): a position offset of the whole cycle.
    A one-sided load (the Cranfield rig's) holds the nut on one flank of a play, so a play
    shows so, not at the reversals."""
    v = np.array(list(shifts.values()))
    return bool(len(v) > 1 and (np.all(v > 0) or np.all(v < 0))
                and np.min(np.abs(v)) >= 0.5 * np.max(np.abs(v)))


def shift_text(shifts: dict[str, float]) -> str:
    """The verdict's words on a position-error index: each phase's shift in mm."""
    if not shifts:
        return ""
    return ("; the mean position error of each phase against the healthy mean: "
            + ", ".join(f"{k} {v:+.3f} mm" for k, v in shifts.items()))


def is_offset(f: Any) -> bool:
    """The cycle's largest phase index is a mean position error, and every phase's moved
    alike (`common_shift`): named `offset` instead of `index` (a name only, the cycle
    was flagged by the index feature)."""
    return f.index_at.endswith("position_error_mean") and common_shift(f.position_shift_mm)


def signed_level(f: Any) -> float:
    """The level's sign-keeping value: the mean of the out- and in-stroke residual means
    (the score is its magnitude). Below zero the current is lowered in both directions:
    less drag, not friction."""
    v = [x for x in (f.level_out, f.level_in) if math.isfinite(x)]
    return float(np.mean(v)) if v else nan_
