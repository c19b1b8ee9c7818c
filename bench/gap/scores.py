"""The held-out gap's scores the ranking and the JSON share: the excess above the noise
floor (or a calibration's healthy energy) and the shrink of that excess by an effect."""

from __future__ import annotations

import math
from typing import Any


def excess(energies: dict[str, float], reference: dict[str, Any] | None = None) -> float:
    """The held-out gap excess X of `energies` (residual energy / floor per signal): the
    sum of E_s - 1, 0 at the noise floor. Against a calibration that stored the energy its
    model leaves on a held-out healthy log (`reference["energy"]`), the sum
    of what each signal has above that healthy energy (and above the floor): the part of
    the gap the calibrated model does not leave on a healthy log, which is what an effect
    can explain (docs/gap.md, "Calibration")."""
    ref = (reference or {}).get("energy")
    if not ref:
        return float(sum(e - 1.0 for e in energies.values()))
    return float(sum(max(e - max(ref.get(s, 1.0), 1.0), 0.0) for s, e in energies.items()))


def shrink_pct(before: float, after: float) -> float:
    """Held-out shrink of the excess gap (%), at most 100 (NaN without a gap before)."""
    if not (math.isfinite(before) and before > 1e-9):
        return float("nan")
    return float(min(100.0, 100.0 * (before - after) / before))
