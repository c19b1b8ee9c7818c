"""Rows of thesis value vs project value, their markdown table and generated doc sections."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench import BenchError


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
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if not math.isfinite(v):
            return "-"
        a = abs(v)
        if a != 0 and (a >= 1e5 or a < 1e-3):
            return f"{v:.4g}"
        return f"{v:.4g}"
    return str(v)


def check(rows: list[Row]) -> list[str]:
    """Ids of rows that differ by more than 10 % and give no reason."""
    return [r.id for r in rows if r.needs_reason() and not r.why.strip()]


def markdown(rows: list[Row]) -> str:
    out = ["| id | quantity | unit | thesis | project | ratio | why they differ |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        ratio = r.ratio
        rs = f"{ratio:.3f}" if math.isfinite(ratio) else ""
        cells = [r.id, r.quantity, r.unit, fmt(r.thesis), fmt(r.project), rs, r.why]
        out.append("| " + " | ".join(c.replace("\n", " ").replace("|", "\\|")
                                     for c in cells) + " |")
    return "\n".join(out) + "\n"


def replace_section(path: str | Path, name: str, body: str) -> Path:
    """Replace the text between ``<!-- name:begin -->`` and ``<!-- name:end -->`` in
    `path` (appending the markers and body when the file lacks them)."""
    path = Path(path)
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    block = f"{begin}\n{body.rstrip()}\n{end}"
    text = section_text(path, name)
    if begin in text and end in text:
        pat = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.S)
        text = pat.sub(lambda _m: block, text, count=1)
    else:
        text = (text.rstrip() + "\n\n" if text.strip() else "") + block + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def section_text(path: str | Path, name: str) -> str:
    """The text of `path` ("" if it does not exist) in which section `name` can be
    replaced: BenchError if it cannot be read as text or has only one of the markers
    (checked before the work by `bench.cli.outputs.check_doc_section`)."""
    path = Path(path)
    if not path.exists():
        return ""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise BenchError(f"{path}: cannot read it as text ({exc})") from None
    if (f"<!-- {name}:begin -->" in text) != (f"<!-- {name}:end -->" in text):
        raise BenchError(f"{path}: unbalanced generated-section markers for {name!r}")
    return text


def figure_links(paths: list[Path] | None, doc_dir: Path | None = None) -> list[str]:
    """Markdown image lines for `paths`, relative to `doc_dir` where they lie under it."""
    out = []
    for p in paths or []:
        rel = Path(p)
        if doc_dir is not None:
            try:
                rel = Path(p).resolve().relative_to(Path(doc_dir).resolve())
            except ValueError:
                rel = Path(p)
        out.append(f"![{Path(p).stem}]({rel.as_posix()})")
    return out

