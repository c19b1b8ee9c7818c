"""One cycle's verdict against a rig's healthy baseline, as one small value.

The same verdict reaches `bench rig assess`, `bench rig study`, and `bench gap` /
`bench hums report` of a rig log judged against a baseline (`fallback.assess`): all of
them build it with `features.verdict`, so one cycle gets one verdict wherever it is read.

It carries: the level in the bench's shared vocabulary (HEALTHY: judged and nothing above
its threshold; WARNING: a deviation from the healthy baseline; UNKNOWN: not judged, e.g.
an incomplete cycle; the rig has no failure threshold of its own, so never FAILURE); the
signature named (`features.EFFECTS`) and the fault family it points to
(`naming.FAULTS`); where a located effect is; every feature against its threshold; the
baseline it was judged against; whether that baseline is provisional (fewer than 3
healthy runs: too few to estimate the spread between runs); and, when a supervised model
classified the cycle, its class.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

HEALTHY, WARNING, FAILURE, UNKNOWN = "HEALTHY", "WARNING", "FAILURE", "UNKNOWN"
PROVISIONAL = "with a provisional baseline"


@dataclass(frozen=True)
class RigVerdict:
    """The verdict of one cycle (module doc)."""
    cycle: str
    level: str                      # HEALTHY, WARNING or UNKNOWN
    effect: str                     # the signature named; "none"; "not judged"
    fault: str                      # naming.FAULTS, "" when not flagged
    text: str
    baseline: str
    provisional: bool = False
    location_mm: float | None = None
    reasons: list[str] = field(default_factory=list)
    supervised: str | None = None   # the supervised model's class, when one was given

    @property
    def judged(self) -> bool:
        return self.level != UNKNOWN

    @property
    def flagged(self) -> bool:
        return self.level == WARNING

    def to_dict(self) -> dict[str, Any]:
        """The verdict as the JSON of `bench rig assess --json` and of the gap and HUMS
        reports (`verdict` is the text)."""
        out: dict[str, Any] = {"cycle": self.cycle, "level": self.level,
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
