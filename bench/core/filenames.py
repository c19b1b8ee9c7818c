"""File names made from data, and the inputs a command must not overwrite.

Every file a writer names after a value of the data (an actuator id, a serial number, a
split key, a log's name) goes through `data_file`: `safe_name` keeps it one name inside
the folder given (path separators, control characters, a leading dot or dash and every
character outside letters, digits and ``-_.=+,@`` become ``_``), bounds its length
(MAX_NAME_BYTES of UTF-8), and when it had to change the text it adds a short hash of
the text (``-`` and 8 hex digits of its sha256), so that distinct values keep distinct
names (``EMA 7``, ``EMA/7`` and ``EMA_7`` give three files).

`protect` holds, while a command runs, the files it reads (the CLI sets it up from the
command's inputs, `bench.cli.outputs`); `check_not_input` refuses (BenchError) a file
about to be written that is one of them, which `data_file` does for every name it makes.
`distinct_labels` names logs given by path for people: the file name, with as many of
its parent folders as it takes to tell two logs apart.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from bench import BenchError

MAX_NAME_BYTES = 96
"""A made name's UTF-8 length at most, before its hash suffix and file suffix (a file
name may have 255 bytes on Linux, macOS and Windows file systems)."""
_KEEP = frozenset("-_.=+,@")

_PROTECTED: list[tuple[tuple[int, int], str]] = []
"""(device, inode) and the name as given of each input of the running command."""


def safe_name(text: str, max_bytes: int = MAX_NAME_BYTES) -> str:
    """`text` as one file name (module docstring): unchanged when it already is a short,
    plain one, else cleaned, bounded and suffixed with ``-`` and 8 hex digits of the
    sha256 of `text`."""
    text = str(text)
    out = "".join(c if (c.isalnum() and c.isprintable()) or c in _KEEP else "_"
                  for c in text)
    if out[:1] in (".", "-"):
        out = "_" + out[1:]
    raw = out.encode("utf-8")
    if len(raw) > max_bytes:
        out = raw[:max_bytes].decode("utf-8", errors="ignore")
    if out == text and out:
        return out
    return f"{out or '_'}-{hashlib.sha256(text.encode('utf-8', 'surrogatepass')).hexdigest()[:8]}"


def data_file(directory: str | Path, text: str, suffix: str = "") -> Path:
    """The file ``directory/<safe_name(text)><suffix>``: always directly inside
    `directory`, never one of the running command's inputs (BenchError)."""
    name = safe_name(text) + suffix
    path = Path(directory) / name
    if path.parent != Path(directory) or name in (".", ".."):   # cannot happen; kept honest
        raise BenchError(f"{directory}: {text!r} does not make a file name in it")
    check_not_input(path)
    return path


def distinct_labels(paths: Sequence[str | Path]) -> list[str]:
    """A label per path for tables and reports: its file name, or as many of its last
    path parts as make the labels of distinct paths distinct (``a/run.log`` and
    ``b/run.log``); a path given twice gets `` (2)``, `` (3)``...; ``-`` (standard
    input) is ``stdin``."""
    parts = [("stdin",) if str(p) == "-" else Path(os.path.abspath(p)).parts for p in paths]
    depth = [1] * len(parts)
    while True:
        labels = ["/".join(pp[-d:]) for pp, d in zip(parts, depth, strict=True)]
        grew = False
        for i, lab in enumerate(labels):
            clash = [j for j, other in enumerate(labels) if other == lab and parts[j] != parts[i]]
            if clash and depth[i] < len(parts[i]):
                depth[i] += 1
                grew = True
        if not grew:
            break
    seen: dict[str, int] = {}
    out = []
    for lab in labels:
        seen[lab] = seen.get(lab, 0) + 1
        out.append(lab if seen[lab] == 1 else f"{lab} ({seen[lab]})")
    return out


def one_line(text: str) -> str:
    """`text` for one line of a table or a message: a character that does not show (a
    newline, a tab, any control character) written as its escape (``\\n``), so data
    cannot forge a line of its own."""
    text = str(text)
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _identity(path: str | Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino)


@contextmanager
def protect(inputs: Iterable[str | Path]) -> Iterator[None]:
    """While the block runs, `check_not_input` refuses to write any of `inputs` (the
    files that exist; the same file under another name or a link included)."""
    added = [(ident, str(p)) for p in inputs if (ident := _identity(p)) is not None]
    _PROTECTED.extend(added)
    try:
        yield
    finally:
        for item in added:
            _PROTECTED.remove(item)


def input_named(path: str | Path) -> str | None:
    """The input (as given) that `path` is, under `protect`; None if it is none."""
    if not _PROTECTED:
        return None
    ident = _identity(path)
    if ident is None:
        return None
    return next((name for i, name in _PROTECTED if i == ident), None)


def check_not_input(path: str | Path, what: str = "") -> None:
    """BenchError when `path` is an input of the running command (`protect`)."""
    name = input_named(path)
    if name is not None:
        same = "" if os.path.abspath(name) == os.path.abspath(path) else f" (the same file as {name})"
        raise BenchError(f"{what + ': ' if what else ''}{path} is an input of this "
                         f"command{same}: writing it would overwrite it; write elsewhere")
