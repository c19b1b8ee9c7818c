"""Reading a report page back: its tables as rows of cell texts (`tables`), the summary
table (`summary`), and whether a cell shows a number (`shows`)."""

from __future__ import annotations

import math
import re
from html.parser import HTMLParser
from pathlib import Path

NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?", re.IGNORECASE)


class _Tables(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tables: list[tuple[str, list[list[str]]]] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append((dict(attrs).get("class") or "", []))
        elif tag == "tr":
            self.tables[-1][1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][1][-1].append(" ".join("".join(self._cell).split()))
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def tables(page: str | Path) -> list[tuple[str, list[list[str]]]]:
    """(class, rows) of every table of the page (a path or its text)."""
    p = _Tables()
    p.feed(Path(page).read_text() if isinstance(page, Path) else page)
    return p.tables


def summary(page: str | Path) -> list[dict[str, str]]:
    """The page's one summary table (class ``summary``) as a dict per row, by header."""
    found = [rows for cls, rows in tables(page) if cls == "summary"]
    assert len(found) == 1, f"{len(found)} summary tables"
    head, *rows = found[0]
    assert rows and all(len(r) == len(head) for r in rows)
    return [dict(zip(head, r, strict=True)) for r in rows]


def numbers(cell: str) -> list[str]:
    """The numbers a cell shows, as written."""
    return NUMBER.findall(cell.replace("\u2212", "-"))


def shows(text: str, value: float, scale: float = 1.0) -> bool:
    """Whether `text` (one number as written) is `value` * `scale` rounded to the digits
    it shows: 0.759 shows 0.75912, not 0.7603."""
    v = value * scale
    if not math.isfinite(v):
        return False
    mant, _, exp = text.lower().partition("e")
    decimals = len(mant.partition(".")[2])
    unit = 10.0 ** (-decimals + (int(exp) if exp else 0))
    return abs(float(text) - v) <= 0.5 * unit * (1 + 1e-9) + 1e-12 * abs(v)
