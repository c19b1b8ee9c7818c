"""The fault a flagged cycle's signatures point to, from physics alone (no labels).

Each feature above its threshold (`features.FEATURES`, as a ratio to the threshold) is
a signature of a fault family:

- spall (a defect on the raceway): a position-locked transient (`localised`) or a
  position-periodic one at the screw's lead (`periodic`);
- friction growth (a lack of lubrication, a worn or contaminated screw): the current
  raised in both directions of motion (`level`, each stroke's own level above the
  healthy one: a load change raises one direction and lowers the other);
- backlash (a play between screw and nut, a preload lost): lost motion at a reversal
  (`takeup`: a one-sided load holds the nut on one flank of a play, so the play shows at
  the one reversal where the drive's force changes sign: which one the load's sign
  decides, and the feature takes either), a position-error hysteresis: the lag while
  taking up both reversals changed alike along the motion (`hysteresis`, a position
  offset that moves from run to run cancelled) or between the strokes' travel
  (`reversal`), the drag of the preload lowered in both directions (`drag`), the current
  rough along the whole travel (`rattle`: a nut no longer held on both flanks moves
  within its play as the drive's force ripples), or every phase's position error moved
  alike under a one-sided load (`offset`), or several of the play's weak signatures
  together (`play`: the hysteresis, the reversal, the take-up and the rattle each as its
  excess over its own threshold, added, `play.play_score`: a play's lag and rattle
  can each stay within the healthy spread while together they do not);
- the current alone while a stroke takes up its reversal (`turn`): a breakaway friction
  and a play's free run and impact both change it, so on its own it names "friction or
  backlash: indistinguishable on this log".

The spall signatures read the travel between the take-ups only (`features.travel_start`):
at a reversal the drive's own dynamics (and a play, and a breakaway) move the current,
and a transient there is not a spot of the raceway.

Friction also lags a stepper or a position loop behind its set-point, so it leaves a
position-error hysteresis of its own: when friction and backlash signatures are both
above their thresholds and neither is `CLEAR` times the other, the fault is "friction
or backlash: indistinguishable on this log" rather than a guess. A lag of the nut at the
reversals or between the strokes is a play's, not a spall's. A periodic line with no spot
of its own (the localised scan below its threshold) is the once-per-revolution ripple
changed along the whole stroke, which any change of the nut's contact with the screw
makes (a lubricant lost, a preload lost, a raceway worn); beside it, the family whose own
signature along the whole stroke is above its threshold is named: a level raised in both
directions is friction's, a drag lowered in both directions, a rattle or the play's
signatures together a play's (a spot on the raceway neither raises nor lowers both
strokes' current, nor makes the whole stroke rough). Otherwise the family whose
strongest signature is furthest above its threshold is named (`attribute`). A cycle
flagged only by a catch-all (a dwell transient, a phase index, a level raised in one
direction only) is "unattributed".
"""

from __future__ import annotations

import math
import re

SPALL, FRICTION, BACKLASH = "spall", "friction", "backlash"
AMBIGUOUS = "friction or backlash"
UNATTRIBUTED = "unattributed"
FAULTS = (SPALL, FRICTION, BACKLASH, AMBIGUOUS, UNATTRIBUTED)
TEXT = {
    SPALL: "spall-like (a position-locked or position-periodic effect)",
    FRICTION: "friction growth (current raised in both directions)",
    BACKLASH: "backlash-like (lost motion at a reversal, a position-error hysteresis, "
              "the preload's drag lost, a play's rattle or its signatures together)",
    AMBIGUOUS: "friction or backlash: indistinguishable on this log",
    UNATTRIBUTED: "no fault family (only a catch-all feature is above its threshold)",
}
CLEAR = 2.0
"""Friction and backlash signatures both above their thresholds: one is named when its
ratio to its threshold is at least this many times the other's."""

# the signatures (effects) of each family; `drag` and `offset` are named by the level and
# the index feature (`features.FEATURE_OF`)
SIGNATURES = {SPALL: ("periodic", "localised"), FRICTION: ("level",),
              BACKLASH: ("takeup", "hysteresis", "reversal", "drag", "offset", "rattle",
                         "play"),
              AMBIGUOUS: ("turn",)}


def family_ratios(above: dict[str, float], level_sign: int, offset: bool
                  ) -> dict[str, tuple[float, str]]:
    """Per family, (the largest ratio of its signatures among `above` (feature -> ratio
    to threshold, only those above 1), the signature). `level_sign`: +1 when the current
    is raised in both directions, -1 lowered in both, 0 otherwise; `offset`: the index
    feature is a position offset in every phase (`features.is_offset`)."""
    sig = dict(above)
    lev = sig.pop("level", None)
    if lev is not None and level_sign > 0:
        sig["level"] = lev
    elif lev is not None and level_sign < 0:
        sig["drag"] = lev
    idx = sig.pop("index", None)
    if idx is not None and offset:
        sig["offset"] = idx
    out: dict[str, tuple[float, str]] = {}
    for fam, keys in SIGNATURES.items():
        best = max((k for k in keys if k in sig), key=lambda k: sig[k], default="")
        if best:
            out[fam] = (sig[best], best)
    return out


POSITION = ("takeup", "hysteresis", "reversal", "offset")   # the backlash signatures of the nut's lag


def attribute(above: dict[str, float], level_sign: int, offset: bool
              ) -> tuple[str, str]:
    """(the fault family, the signature named) of a flagged cycle (module doc), in order:

    1. friction (the level raised in both directions) and backlash both: the one at least
       `CLEAR` times the other's ratio, else "friction or backlash";
    2. a backlash signature of the nut's lag (`POSITION`): backlash, whatever the current
       does besides: a spot on the raceway loads the nut, it does not make it lag the motor
       at the reversals or between the strokes;
    3. friction or backlash beside a spall's periodic line with no spot of its own (the
       localised scan below its threshold): that family (its signature here: the level
       raised in both directions, or the drag lowered in both directions, the rattle or
       the play's signatures together),
       since a lubricant lost, a preload lost or a screw worn changes the
       once-per-revolution ripple along the whole stroke too, but a spot on the raceway
       neither moves both strokes' current nor makes the whole stroke rough;
    4. else the family whose strongest signature is furthest above its threshold (the
       current at a reversal alone beside the level is friction's breakaway: it names
       "friction or backlash" only when nothing else is above);
    5. else unattributed, its strongest catch-all (dwell, index, or `level` when only one
       direction moved) the signature."""
    fams = family_ratios(above, level_sign, offset)
    if not fams:
        best = max(above, key=lambda k: above[k]) if above else "none"
        return UNATTRIBUTED, best
    if FRICTION in fams and BACKLASH in fams:
        f, b = fams[FRICTION][0], fams[BACKLASH][0]
        if f >= CLEAR * b:
            return FRICTION, fams[FRICTION][1]
        if b >= CLEAR * f:
            return BACKLASH, fams[BACKLASH][1]
        return AMBIGUOUS, fams[FRICTION if f >= b else BACKLASH][1]
    lag = max((k for k in POSITION if k in above or (k == "offset" and offset)),
              key=lambda k: above.get(k, above.get("index", 0.0)), default="")
    if lag and BACKLASH in fams:
        return BACKLASH, lag
    if fams.get(SPALL, (0.0, ""))[1] == "periodic" and "localised" not in above:
        # after 1. and 2., backlash's signatures here are the drag, the rattle, the play
        for fam in (FRICTION, BACKLASH):
            if fam in fams:
                return fam, fams[fam][1]
    rest = {k: v for k, v in fams.items() if k != AMBIGUOUS}
    if rest:
        fam = max(rest, key=lambda k: rest[k][0])
        return fam, rest[fam][1]
    return AMBIGUOUS, fams[AMBIGUOUS][1]


def level_sign(level_out: float, level_in: float) -> int:
    """+1 when both strokes' current is above the healthy one, -1 when both are below, 0
    otherwise (a one-sided change, or a stroke missing)."""
    if not (math.isfinite(level_out) and math.isfinite(level_in)):
        return 0
    if level_out > 0 and level_in > 0:
        return 1
    if level_out < 0 and level_in < 0:
        return -1
    return 0


# what a table's label (`classify.table_label`) says the fault is, for scoring the
# physics names of a development set: the label's words, not a rule of the detector
EXPECTED = ((r"backlash|play|lostmotion", BACKLASH),
            (r"lubric|lube|friction|grease", FRICTION),
            (r"spall|pit|raceway", SPALL))


def expected_fault(label: str) -> str | None:
    """The physics family a fault table's label names (`EXPECTED`), None when it names
    none (a healthy table, or a fault the families do not cover)."""
    low = label.lower()
    for pattern, fam in EXPECTED:
        if re.search(pattern, low):
            return fam
    return None


def is_correct(fault: str, expected: str | None) -> bool:
    """A physics name is right when it is the expected family; "friction or backlash"
    is not (it is honest, not right)."""
    return expected is not None and fault == expected
