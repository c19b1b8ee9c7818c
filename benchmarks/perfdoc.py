"""Shared by the benchmark scripts: replace one `## ` section of docs/performance.md."""

from __future__ import annotations

import re
from pathlib import Path


def write_section(path: str | Path, text: str) -> None:
    """Replace the section whose first line is `text`'s first line (a ``## `` header),
    up to the next ``## `` header, with `text`; append it when the file has none."""
    path = Path(path)
    header = text.splitlines()[0]
    body = text.rstrip("\n") + "\n"
    old = path.read_text() if path.exists() else "# Performance\n"
    pat = re.compile(r"^" + re.escape(header) + r"$.*?(?=^## |\Z)", re.S | re.M)
    if pat.search(old):
        new = pat.sub(lambda m: body + ("\n" if m.end() < len(old) else ""), old, count=1)
    else:
        new = old.rstrip("\n") + "\n\n" + body
    path.write_text(new)


def publish(text: str, path: str | Path | None) -> None:
    """Print a benchmark's section, and with a path (`--write`) put it there too."""
    print(text)
    if path:
        write_section(path, text)
