"""Output paths checked before the work that fills them (issue 9 item 13): a command that
runs for minutes must not find out at the end that it cannot write its result.

`check_output_file` and `check_output_dir` raise a one-line BenchError naming the flag
when the suffix is unknown, the target is of the wrong kind, or the directory does not
exist or cannot take a new file (probed by creating and removing a temporary file there,
which also catches read-only file systems and works for root). They create nothing.
A directory the command creates with its parents (`check_output_dir`, and the parent of a
file with ``make_parents=True``) need not exist: its nearest existing ancestor must be a
directory that can take a new file (no component of the path is a file).
`check_outputs` checks a command's output options by name, `check_doc_section` a markdown
file whose generated section the command replaces.
"""

from __future__ import annotations

import os
import tempfile
from argparse import Namespace
from collections.abc import Iterable
from pathlib import Path

from bench import BenchError


def _probe(directory: Path) -> bool:
    """True when a new file can be created in `directory` (tried, then removed)."""
    try:
        with tempfile.NamedTemporaryFile(dir=directory, prefix=".bench-probe-"):
            return True
    except OSError:
        return False


def _creatable(p: Path, what: str, flag: str) -> None:
    """Directory `p`, which does not exist, can be made with its parents (BenchError
    `flag: cannot write {what}: ...` if not): its nearest existing ancestor is a directory
    that can take a new file."""
    base = p.parent
    while not os.path.lexists(base) and base != base.parent:
        base = base.parent
    if not os.path.isdir(base):
        raise BenchError(f"{flag}: cannot write {what}: {base} is not a directory")
    if not _probe(base):
        raise BenchError(f"{flag}: cannot write {what}: directory {base} is not writable")


def check_output_file(path: str | Path, flag: str, suffixes: Iterable[str] | None = None,
                      stdout_ok: bool = False, make_parents: bool = False) -> Path:
    """`path` as a file the command can write (BenchError `flag: ...` if not).

    `suffixes`: the known ones, lower case with the dot; `stdout_ok`: "-" means stdout;
    `make_parents`: the command creates the missing parent directories."""
    p = Path(path)
    if stdout_ok and str(path) == "-":
        return p
    known = tuple(suffixes or ())
    if os.path.isdir(p):
        raise BenchError(f"{flag}: cannot write {p}: it is a directory")
    if known and p.suffix.lower() not in known:
        raise BenchError(f"{flag}: {p}: unknown suffix {p.suffix!r} (use {', '.join(known)})")
    parent = p.parent
    if make_parents and not os.path.lexists(parent):
        _creatable(parent, str(p), flag)
        return p
    if make_parents and not os.path.isdir(parent):
        raise BenchError(f"{flag}: cannot write {p}: {parent} is not a directory")
    if not os.path.isdir(parent):
        raise BenchError(f"{flag}: cannot write {p}: directory {parent} does not exist")
    if p.exists():
        if not os.access(p, os.W_OK):
            raise BenchError(f"{flag}: cannot write {p}: permission denied")
    elif not _probe(parent):
        raise BenchError(f"{flag}: cannot write {p}: directory {parent} is not writable")
    return p


def check_output_dir(path: str | Path, flag: str) -> Path:
    """`path` as a directory the command can create (with its parents) and write into."""
    p = Path(path)
    if not os.path.lexists(p):
        _creatable(p, f"into {p}", flag)
        return p
    if not os.path.isdir(p):
        raise BenchError(f"{flag}: cannot write into {p}: it is not a directory")
    if not _probe(p):
        raise BenchError(f"{flag}: cannot write into {p}: directory {p} is not writable")
    return p


def check_outputs(args: Namespace, files: Iterable[str] = (), dirs: Iterable[str] = (),
                  make_parents: bool = True) -> None:
    """The output options of `args` that are given (attributes `files`, written as files,
    and `dirs`, directories made with their parents; `--name-with-dashes` in messages),
    checked before the work. `make_parents`: the files' missing directories are made."""
    for name in files:
        if getattr(args, name, None):
            check_output_file(getattr(args, name), _flag(name), make_parents=make_parents)
    for name in dirs:
        if getattr(args, name, None):
            check_output_dir(getattr(args, name), _flag(name))


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def check_doc_section(path: str | Path, name: str, flag: str = "--doc") -> Path:
    """Markdown file `path` (made with its parents if missing) whose generated section
    `name` the command replaces (`bench.hums.table.replace_section`): writable, and when
    it exists readable as text with its section markers balanced."""
    from bench.hums.table import section_text
    p = check_output_file(path, flag, make_parents=True)
    if os.path.lexists(p):
        try:
            section_text(p, name)
        except BenchError as exc:
            raise BenchError(f"{flag}: {exc}") from None
    return p
