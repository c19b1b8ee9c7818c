"""A play's weak signatures together: the `play` feature of `features.cycle_features`
(naming-only), each of the take-up, the hysteresis, the reversal and the rattle counted
by its excess over its own threshold and added, so that several signatures each raised
but below its threshold name a play as one far above does."""

from __future__ import annotations

import math

NAN = float("nan")
PLAY = "play"
PLAY_OF = ("hysteresis", "reversal", "takeup", "rattle")
"""The play's weak signatures whose evidence `play_score` adds (none need be above its
own threshold)."""
TWO_SIDED = ("hysteresis", "reversal")
"""Of `PLAY_OF`, the signed scores whose healthy null is a normal about 0 (the others' is
a log-normal)."""


def play_score(scores: dict[str, float], thresholds: dict[str, float]) -> float:
    """A play's weak signatures together (`PLAY_OF`): exp of the sum of each one's excess
    over its own threshold on the scale its healthy null is modelled on
    (`population.NULLS`): log(score / threshold) for the log-normal take-up and rattle,
    score / threshold - 1 for the two-sided hysteresis and reversal (their |value|, a
    normal's about 0: its log runs to minus infinity near 0, where a healthy score often
    is). Several signatures each raised but below its threshold add up, as one far above
    does; NaN when a signature or its threshold is missing."""
    tot = 0.0
    for k in PLAY_OF:
        v, t = scores.get(k, NAN), thresholds.get(k, NAN)
        if not (math.isfinite(v) and math.isfinite(t) and t > 0):
            return NAN
        tot += v / t - 1.0 if k in TWO_SIDED else math.log(max(v, 1e-9) / t)
    return math.exp(tot)


def hysteresis(mm: dict[str, float], zz: dict[str, float]) -> float:
    """A position-error hysteresis over the take-ups of the reversals (`takeup`'s values):
    the lag along the motion changed alike at both reversals, (mm_out + mm_in) over its
    standard error. A position offset (the sensor's zero, or the nut held on one flank,
    that moves from run to run) moves the out- and in-stroke error the same way, i.e.
    along the motion by +d on one stroke and -d on the other, and cancels; a play adds
    to both, or to the one reversal a one-sided load leaves it on. NaN without both."""
    if not all(k in mm and k in zz and zz[k] != 0 for k in ("out", "in")):
        return float("nan")
    se = math.hypot(mm["out"] / zz["out"], mm["in"] / zz["in"])
    return (mm["out"] + mm["in"]) / se if se > 0 else float("nan")
