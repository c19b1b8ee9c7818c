"""The usage as a readable table: one row per run or per actuator."""

from __future__ import annotations

import math

from bench.usage.hysteresis import text
from bench.usage.summary import UsageSummary

COLUMNS = (
    ("actuator", 10, lambda s: s.actuator_serial),
    ("runs", 4, lambda s: f"{s.runs:g}"),
    ("time s", 8, lambda s: f"{s.duration_s:.1f}"),
    ("screw rev", 9, lambda s: _num(s.screw_revolutions, ".2f")),
    ("travel m", 8, lambda s: _num(s.nut_travel_m, ".4f")),
    ("revers.", 7, lambda s: _num(s.reversals, "g")),
    ("pos cyc", 7, lambda s: _num(s.position_cycles, "g")),
    ("load cyc", 8, lambda s: _num(s.load_cycles, "g")),
    ("Fm N", 7, lambda s: _num(s.fm_n, ".0f")),
    ("L10 rev", 9, lambda s: _num(s.l10_rev, ".3g")),
    ("life used", 9, lambda s: _num(s.life_consumed, ".3e")),
    ("I2t A2s", 8, lambda s: _num(s.i2t_a2s, ".4g")),
    ("Tmax K", 6, lambda s: _num(s.temperature_max_k, ".1f")),
    ("dwell/slow/fast s", 17,
     lambda s: "/".join(_num(v, ".1f") for v in (s.dwell_s, s.slow_s, s.fast_s))),
)


def _num(v: float, fmt: str) -> str:
    """`v` formatted; NaN (not available: `notes` says why) as n/a."""
    return format(v, fmt) if math.isfinite(v) else ("n/a" if math.isnan(v) else
                                                     "-" if v < 0 else "inf")


def format_table(rows: list[tuple[str, UsageSummary]]) -> str:
    """Rows of (label, summary) as an aligned text table; the label is the first column."""
    width = max([len("run")] + [len(label) for label, _ in rows])
    head = "run".ljust(width) + "  " + "  ".join(name.rjust(w) for name, w, _ in COLUMNS)
    lines = [head]
    for label, s in rows:
        lines.append(label.ljust(width) + "  " + "  ".join(
            str(get(s)).rjust(w) for _, w, get in COLUMNS))
    return "\n".join(lines)


def notes(label: str, s: UsageSummary) -> list[str]:
    """Lines under the table: the hysteresis of each counter and why
    (`bench.usage.hysteresis`), the quantities `s` has no value for, grouped by reason."""
    why: dict[str, list[str]] = {}
    for q, reason in s.not_available.items():
        why.setdefault(reason, []).append(q)
    head = [f"{label}: hysteresis: {text(s.hysteresis)}"] if s.hysteresis else []
    return head + [f"{label}: not available ({reason}): {', '.join(qs)}"
                   for reason, qs in why.items()]
