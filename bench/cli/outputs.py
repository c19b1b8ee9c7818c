"""Output paths checked before the work that fills them: a command that runs for minutes
must not find out at the end that it cannot write its result, and no command writes over
a file it reads.

`check_output_file` and `check_output_dir` raise a one-line BenchError naming the flag
when the suffix is unknown, the target is of the wrong kind, or the directory does not
exist or cannot take a new file (probed by creating and removing a temporary file there,
which also catches read-only file systems and works for root). They create nothing.
A directory the command creates with its parents (`check_output_dir`, and the parent of a
file with ``make_parents=True``) need not exist: its nearest existing ancestor must be a
directory that can take a new file (no component of the path is a file).
`check_outputs` checks a command's output options by name, `check_doc_section` a markdown
file whose generated section the command replaces.

`check_io` runs before every command (`bench.cli._main`): from `IO`, the table of every
command's inputs and outputs by option name, it refuses an output that resolves to one
of the command's inputs (the same file, also through a link or another name: samefile),
a fixed-name file an output directory would get that is an input (``fleet export --out``
into the store's folder when the store is ``runs.parquet``), an output directory that is
an input file, and two outputs at one path; `inputs` gives the files `bench.core.filenames.protect`
then guards while the command runs (files named from data, e.g. ``import --split-by``,
are checked as they are named).
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
    if name == "output":
        return "-o"
    if name == "file":
        return "FILE"
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


# --- inputs and outputs of every command -------------------------------------------------

class IO:
    """One command's files by option name (the argparse ``dest``): `inputs` read (a
    path, or a list of paths; directories and globs allowed), `files` written, `dirs`
    written into, each with the fixed names the command writes there."""

    def __init__(self, inputs: tuple[str, ...] = (), files: tuple[str, ...] = (),
                 dirs: dict[str, tuple[str, ...]] | None = None,
                 empty_is_none: tuple[str, ...] = (), twice_ok: bool = False) -> None:
        self.inputs, self.files, self.dirs = inputs, files, dict(dirs or {})
        self.empty_is_none = empty_is_none
        self.twice_ok = twice_ok
        """The command itself tells a copy from a new input (`fleet ingest`'s digests)."""
        """Options whose help says '' means no such output (`reproduce --figures ''`)."""


_HUMS_REPORT = ("report.html", "indexes.json", "summary.txt")
_GAP_REPORT = ("gap.json", "index.html", "report.html", "indexes.json", "summary.txt",
               "residual_regime_band.png", "traces_before_after.png", "path_residuals.png")
_RIG_STUDY = ("baseline.json", "study.json", "residual.png", "detection.png", "location.png",
              "report.md", "report.html")
_BUS = IO()

IO_TABLE: dict[str, IO] = {
    "demo": IO(dirs={"out": ("summary.json", "healthy.log", "worn.log", "failing.log")}),
    "reproduce": IO(files=("out", "json"), dirs={"figures": ()}, empty_is_none=("figures",)),
    "plant": IO(inputs=("params",), files=("ready_file",)),
    "up": _BUS, "status": _BUS, "down": _BUS,
    "run": IO(files=("log", "save")),
    "log": IO(files=("file",)),
    "replay": IO(inputs=("file",)),
    "decode": IO(inputs=("file",), files=("output",)),
    "hums fit": IO(files=("json",)),
    "hums sweep": IO(files=("json", "doc"), dirs={"figures": ()}),
    "hums rul": IO(files=("json", "doc"), dirs={"figures": ()}),
    "hums campaign": IO(files=("json", "doc", "trends_out", "calibration_out"),
                        dirs={"figures": ()}),
    "hums prognose": IO(inputs=("trends", "calibration"), files=("json",)),
    "hums report": IO(inputs=("logs", "nominal", "baseline"), dirs={"out": _HUMS_REPORT}),
    "hums watch": IO(files=("out", "usage")),
    "usage": IO(inputs=("files",), files=("json",), dirs={"plot": ()}),
    "gap": IO(inputs=("log", "holdout", "nominal", "baseline"), files=("json",),
              dirs={"report": _GAP_REPORT}),
    "gap-bench": IO(files=("json", "markdown")),
    "calibrate": IO(inputs=("log", "holdout", "nominal", "actuator"), files=("output",)),
    "import": IO(inputs=("table", "map"), files=("output",)),
    "fleet ingest": IO(inputs=("paths",), files=("db",), twice_ok=True),
    "fleet status": IO(inputs=("db",)),
    "fleet report": IO(inputs=("db",), dirs={"out": ("index.html", "status.json")}),
    "fleet export": IO(inputs=("db",), dirs={"out": ("runs.parquet", "failures.parquet",
                                                     "meta.parquet")}),
    "fleet synth": IO(dirs={"out": ("fleet-truth.json",)}),
    "rig baseline": IO(inputs=("tables", "actuator"), files=("out",)),
    "rig assess": IO(inputs=("tables", "baseline"), files=("json",)),
    "rig study": IO(inputs=("directory", "actuator", "model"), dirs={"out": _RIG_STUDY}),
    "rig train": IO(inputs=("tables", "actuator"), files=("out", "json")),
    "rig classify": IO(inputs=("model", "tables", "actuator"), files=("json",)),
    "rig inject": IO(inputs=("tables", "actuator"),
                     dirs={"out": ("inject.json", "inject.md", "inject.png")}),
}
"""Every command's files (a unit test checks that every command of `bench` is here)."""


def command_name(args: Namespace) -> str:
    """The command `args` runs, e.g. ``fleet export``."""
    words = [str(getattr(args, "command", "") or "")]
    for group in ("fleet", "hums", "rig"):
        sub = getattr(args, f"{group}_command", None)
        if words[0] == group and sub:
            words.append(str(sub))
    return " ".join(w for w in words if w)


def _paths(value: object) -> list[str]:
    """The paths an option's value names (a list for nargs; "-" is stdin/stdout)."""
    if value is None or value is False or value is True:
        return []
    values = value if isinstance(value, (list, tuple)) else [value]
    return [str(v) for v in values if v is not None and str(v) not in ("", "-")]


def inputs(args: Namespace) -> list[str]:
    """The input files of the command `args` runs (globs expanded; directories as they
    are: what they hold is read by suffix, and a command writes no such file there)."""
    import glob
    io = IO_TABLE.get(command_name(args))
    out: list[str] = []
    for name in io.inputs if io else ():
        for p in _paths(getattr(args, name, None)):
            out.extend(glob.glob(p, recursive=True) if glob.has_magic(p) else [p])
    return out


def same_file(a: str, b: str) -> bool:
    """`a` and `b` are one file: the same path, or both exist and are the same file."""
    if os.path.abspath(a) == os.path.abspath(b) or os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_io(args: Namespace) -> None:
    """Before the command runs: no output of `args` resolves to one of its inputs, and
    no two outputs to one path (BenchError naming the options; module docstring); a
    ``--workers`` count the machine cannot run (`bench.runtime.cluster.check_workers`) and a
    ``--scheduler`` that is no address are refused too."""
    _check_pool(args)
    io = IO_TABLE.get(command_name(args))
    if io is None:
        return
    _no_empty_path(io, args)
    _no_input_twice(io, args)
    ins = [(name, p) for name in io.inputs for p in _paths(getattr(args, name, None))]
    outs = [(name, p) for name in io.files for p in _paths(getattr(args, name, None))]
    for name, fixed in io.dirs.items():
        for d in _paths(getattr(args, name, None)):
            for iname, ip in ins:
                if os.path.isfile(ip) and same_file(d, ip):
                    raise BenchError(f"{_flag(name)} {d}: that is the input {_arg(iname)} "
                                     f"{ip}, not a directory to write into")
            outs.extend((name, os.path.join(d, f)) for f in fixed)
    for name, p in outs:
        for iname, ip in ins:
            if same_file(p, ip):
                raise BenchError(f"{_flag(name)} {p}: that is the input {_arg(iname)} {ip}; "
                                 "writing it would overwrite it: write elsewhere")
    for k, (name, p) in enumerate(outs):
        for name2, p2 in outs[k + 1:]:
            if name2 != name and same_file(p, p2):
                raise BenchError(f"{_flag(name)} and {_flag(name2)} are one file ({p}); "
                                 "give each output its own path")
    _known_suffixes(io, args)


OUTPUT_SUFFIXES = {"json": (".json",), "calibration_out": (".json",),
                   "markdown": (".md", ".markdown")}
"""The suffix an output option's file must have, by option name: a `--json` written over
a candump log or a `--markdown` over a CSV destroyed it."""


def _known_suffixes(io: IO, args: Namespace) -> None:
    """Each output file of a kind `OUTPUT_SUFFIXES` names has its suffix ("-": stdout; a
    directory is left to the command's own check, which says so), worded as
    `check_output_file` words it."""
    for name in io.files:
        known = OUTPUT_SUFFIXES.get(name, ())
        for p in _paths(getattr(args, name, None)) if known else []:
            if not os.path.isdir(p) and Path(p).suffix.lower() not in known:
                raise BenchError(f"{_flag(name)}: {p}: unknown suffix {Path(p).suffix!r} "
                                 f"(use {', '.join(known)})")


def _no_empty_path(io: IO, args: Namespace) -> None:
    """No path option given as "" (or blanks): for a folder it meant the current one
    (`--out ""` wrote the report there), for a file nothing written and no word said."""
    for name in (*io.inputs, *io.files, *io.dirs):
        if name in io.empty_is_none:
            continue
        value = getattr(args, name, None)
        if any(isinstance(v, str) and not v.strip()
               for v in (value if isinstance(value, (list, tuple)) else [value])):
            raise BenchError(f"{_arg(name)}: an empty path: name a file or folder")


def _no_input_twice(io: IO, args: Namespace) -> None:
    """No input file given twice to one option (the same file, also under another name or
    through a link, or a copy of its bytes): it would count twice (`bench usage a.log
    a.log` summed the run's usage twice; a table and its copy made a baseline of each run
    twice)."""
    for name in () if io.twice_ok else io.inputs:
        value = getattr(args, name, None)
        if not isinstance(value, (list, tuple)):
            continue
        files = [p for p in _paths(value) if os.path.isfile(p)]
        for k, p in enumerate(files):
            for q in files[k + 1:]:
                if same_file(p, q):
                    raise BenchError(f"{_arg(name)}: {p} and {q} are one file, given twice: "
                                     "give each input once")
                if same_bytes(p, q):
                    raise BenchError(f"{_arg(name)}: {p} and {q} hold the same bytes (one "
                                     "file under two names?): give each input once")


def same_bytes(a: str, b: str) -> bool:
    """Files `a` and `b` hold the same bytes (sizes first; read only when they agree)."""
    import filecmp
    try:
        return os.path.getsize(a) == os.path.getsize(b) and filecmp.cmp(a, b, shallow=False)
    except OSError:
        return False


def _check_pool(args: Namespace) -> None:
    """`--workers` and `--scheduler`, for every command that has them: a scheduler must
    answer as one (`bench.runtime.cluster.probe_scheduler`) before anything is written."""
    if getattr(args, "workers", None) is not None or getattr(args, "scheduler", None):
        from bench.runtime.cluster import check_workers, probe_scheduler, scheduler_address
        addr = scheduler_address(getattr(args, "scheduler", None))
        if addr is not None:
            probe_scheduler(addr)
        check_workers(getattr(args, "workers", None), addr)


def _arg(name: str) -> str:
    """An input's name in messages: an option's flag, a positional's upper-case name."""
    positional = {"logs": "LOG", "files": "LOG_OR_TRACE", "log": "LOG", "file": "FILE",
                  "table": "TABLE", "tables": "TABLE", "paths": "PATH", "directory": "DIR"}
    return positional.get(name, _flag(name))
