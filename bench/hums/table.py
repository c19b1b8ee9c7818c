"""Generated doc sections: a page's text between markers replaced, figure links (the rows
themselves and their table: `bench.core.thesis_rows`)."""

from __future__ import annotations

import re
from pathlib import Path

from bench import BenchError


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

