"""Rows of thesis value vs project value and their one markdown table: the rows of
`bench reproduce` (thesis ch. 5), of the HUMS sweeps and of the RUL runs (ch. 6).

A row's ratio is project / thesis when both are numbers (and the thesis value is not 0);
a row whose ratio is more than 10 % off 1 needs a reason (`check`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any


@dataclass
class Row:
    """One reproduced number: `thesis` is a number or the thesis' words; `project` is
    what the bench measured. `why` explains a difference above 10 % (or a qualitative
    mismatch); it is required for those rows (`check`)."""
    id: str
    quantity: str
    unit: str
    thesis: Any
    project: Any
    why: str = ""

    @property
    def ratio(self) -> float:
        if _num(self.thesis) and _num(self.project) and float(self.thesis) != 0:
            return float(self.project) / float(self.thesis)
        return math.nan

    def needs_reason(self) -> bool:
        r = self.ratio
        return math.isfinite(r) and abs(r - 1.0) > 0.10

    def to_json(self) -> dict[str, Any]:
        def enc(v: Any) -> Any:
            if isinstance(v, float) and not math.isfinite(v):
                return None
            return v
        return {"id": self.id, "quantity": self.quantity, "unit": self.unit,
                "thesis": enc(self.thesis), "project": enc(self.project),
                "ratio": enc(self.ratio), "why": self.why}


def _num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def fmt(v: Any) -> str:
    """A value as the table prints it: 4 significant digits, yes/no, '-' for no number."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if not math.isfinite(v):
            return "-"
        return f"{v:.4g}"
    return str(v)


def check(rows: Sequence[Row]) -> list[str]:
    """Ids of rows that differ by more than 10 % and give no reason."""
    return [r.id for r in rows if r.needs_reason() and not r.why.strip()]


def markdown(rows: Sequence[Row], value: Callable[[Any], str] = fmt,
             reason: Callable[[Row], str] | None = None) -> str:
    """The rows as one markdown table (id, quantity, unit, thesis, project, ratio, why
    they differ); `value` formats a thesis or project value, `reason` gives a row's last
    cell (default: its `why`). A cell's ``|`` and line breaks are escaped."""
    out = ["| id | quantity | unit | thesis | project | ratio | why they differ |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        ratio = r.ratio
        rs = f"{ratio:.3f}" if math.isfinite(ratio) else ""
        why = r.why if reason is None else reason(r)
        cells = [r.id, r.quantity, r.unit, value(r.thesis), value(r.project), rs, why]
        out.append("| " + " | ".join(c.replace("\n", " ").replace("|", "\\|")
                                     for c in cells) + " |")
    return "\n".join(out) + "\n"
