"""One cycle's verdict against a rig's healthy baseline, as one small value.

The same verdict reaches `bench rig assess`, `bench rig study`, and `bench gap` /
`bench hums report` of a rig log judged against a baseline (`fallback.assess`): all of
them build it with `features.verdict`, so one cycle gets one verdict wherever it is read.

It is a `bench.core.verdict.Verdict` (level, effect, reasons, reference: the baseline it was
judged against) with the cycle's label. Its level: HEALTHY (judged and nothing above
its threshold), DEGRADED (a deviation from the healthy baseline: past its threshold, the
level a log with such a cycle gets too) or UNKNOWN (not judged, e.g. an incomplete
cycle); the baseline has no warning or failure level of its own, so never WARNING or
FAILURE.
It adds the fault family the signature points to (`naming.FAULTS`); where a located
effect is; the text; whether the baseline is provisional (fewer than 3 healthy runs:
too few to estimate the spread between runs); and, when a supervised model classified
the cycle, its class.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bench.core.verdict import Level, Verdict

PROVISIONAL = "with a provisional baseline"


@dataclass(frozen=True, kw_only=True)
class RigVerdict(Verdict):
    """The verdict of one cycle (module doc); `effect` is the signature named
    (`features.EFFECTS`), "none" or "not judged"."""
    cycle: str
    fault: str = ""                 # naming.FAULTS, "" when not flagged
    text: str = ""
    provisional: bool = False
    location_mm: float | None = None
    supervised: str | None = None   # the supervised model's class, when one was given

    @property
    def baseline(self) -> str:
        """The baseline it was judged against (the verdict's reference)."""
        return self.reference

    def to_dict(self) -> dict[str, Any]:
        """The verdict as the JSON of `bench rig assess --json` and of the gap and HUMS
        reports (`verdict` is the text)."""
        out: dict[str, Any] = {"cycle": self.cycle, "level": self.level.name,
                               "flagged": self.flagged, "judged": self.judged,
                               "effect": self.effect, "fault": self.fault,
                               "verdict": self.text, "reasons": list(self.reasons),
                               "baseline": self.baseline, "provisional": self.provisional,
                               "location_mm": self.location_mm}
        if self.supervised is not None:
            out["supervised"] = self.supervised
        return out


def provisional_note(runs: int) -> str:
    """The words every verdict against a provisional baseline carries."""
    return (f"{PROVISIONAL} ({runs} healthy run{'s' if runs != 1 else ''}: too few to "
            "estimate the spread between runs)")


def baseline_verdict(res: dict[str, Any], reference: str) -> Verdict | None:
    """A log's verdict against the healthy baseline, from its cycles (a
    `fallback.assess` result): DEGRADED when a judged cycle is outside the baseline's
    thresholds (the effect: the signature most cycles show), else HEALTHY; None when no
    cycle was judged. `bench hums report` and `bench gap` give a rig log this one."""
    if not res["judged"]:
        return None
    reasons = [f"{res['flagged']} of {res['judged_cycles']} cycle(s) outside the healthy "
               f"baseline's thresholds"]
    reasons += [f"{v['cycle']}: {v['verdict']}" for v in res["verdicts"]
                if v["flagged"] or not v["judged"]]
    effects = res.get("effects") or {}
    effect = max(effects, key=lambda k: effects[k]) if effects else "none"
    return Verdict(Level.DEGRADED if res["flagged"] else Level.HEALTHY,
                   effect if res["flagged"] else "none", tuple(reasons), reference)


def model_verdict(m: dict[str, Any], reference: str, pre: tuple[str, ...] = (),
                  effect: str | None = None) -> Verdict:
    """A rig log's verdict against its calibrated generic model (`m`: the RMS ratio of
    each signal to its noise floor, its threshold, whether any is above, the signals not
    judged): DEGRADED when a signal is above its threshold, else HEALTHY; UNKNOWN when a
    signal the calibration's healthy logs were scored on is missing. `effect`: what the
    gap diagnosis named (default: the signals above their thresholds)."""
    reasons = list(pre)
    for s, r in m["rms_ratio"].items():
        side = "above" if r > m["threshold"][s] else "within"
        reasons.append(f"{s} RMS {r:.2f} x its noise floor, {side} the threshold "
                       f"{m['threshold'][s]:.2f} (the calibration's worst healthy ratio, at "
                       "least 2)")
    if m.get("not_judged"):      # a verdict without a signal it rests on is no verdict
        return Verdict.unknown(reasons + [
            "the calibrated model's verdict needs every signal its healthy logs were scored "
            "on; not judged: " + "; ".join(f"{s} ({why})" for s, why in m["not_judged"].items())],
            reference)
    above = [s for s, r in m["rms_ratio"].items() if r > m["threshold"][s]]
    if effect is None:
        effect = ", ".join(above) if m["significant"] else "none"
    return Verdict(Level.DEGRADED if m["significant"] else Level.HEALTHY, effect,
                   tuple(reasons), reference)
