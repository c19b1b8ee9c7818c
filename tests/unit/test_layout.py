"""The tree's shape: no import cycles (between modules, and between packages), no module
over 600 lines, no function over 80 lines without a reason written at its top, and the
layers' arrows pointing one way, and one HTML page skeleton and one base64-PNG helper
(bench/reports).

A long function states why on its first body line, as a comment starting with
``# long:`` (e.g. ``# long: one compiled loop, splitting it costs a call per sub-step``).
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("ema_contract", "plant_rt", "bench", "indie_plant")
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        base = ROOT / pkg
        if not base.is_dir():
            continue
        for path in sorted(base.rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


# Every check below reads the same sources: each file is read, parsed and walked once per
# test process (the trees are only read, never changed).
@functools.cache
def _source(path: Path) -> str:
    return path.read_text()


@functools.cache
def _parse(source: str) -> ast.Module:
    return ast.parse(source)


_WALKED: dict[int, tuple[ast.AST, tuple[ast.AST, ...]]] = {}


def _nodes(tree: ast.AST) -> tuple[ast.AST, ...]:
    """`ast.walk(tree)` as a tuple, kept for the trees `_parse` keeps."""
    if id(tree) not in _WALKED:
        _WALKED[id(tree)] = (tree, tuple(ast.walk(tree)))
    return _WALKED[id(tree)][1]


def _resolve(mod: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = mod.split(".")
    is_pkg = MODULES[mod].name == "__init__.py"
    base = base if is_pkg else base[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


@functools.cache
def _imports(mod: str) -> frozenset[str]:
    """Modules of this tree that `mod` imports anywhere: at module level or inside a
    function (a function-local import does not break a cycle, it only hides it)."""
    tree = _parse(_source(MODULES[mod]))
    found: set[str] = set()

    def add(name: str) -> None:
        while name and name not in MODULES:
            name = name.rpartition(".")[0]
        if name and name != mod:
            found.add(name)

    for st in _nodes(tree):
        if isinstance(st, ast.Import):
            for a in st.names:
                add(a.name)
        elif isinstance(st, ast.ImportFrom):
            base = _resolve(mod, st)
            for a in st.names:
                add(f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base)
    return frozenset(found)


def test_no_import_cycles():
    graph = {m: _imports(m) for m in MODULES}
    cycles = []
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                cycles.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def _package(mod: str) -> str:
    """The package a module belongs to in the package graph: a subpackage of bench
    (``bench.sim``, ``bench.signals``, ``bench.gap``, ...), ``bench`` for bench/__init__
    and bench/__main__, else the top-level package (``ema_contract``, ``plant_rt``,
    ``indie_plant``)."""
    parts = mod.split(".")
    if parts[0] == "bench" and len(parts) > 1 and (ROOT / "bench" / parts[1]).is_dir():
        return f"bench.{parts[1]}"
    return parts[0]


# Importers left out of the package graph, as they may import every package:
# - bench/__init__ and bench/__main__, the entry points (`python -m bench`);
# - the command modules of bench.cli (one per command: they put the packages together
#   and no package imports them). A cli module another package imports (bench.rig's
#   model files use bench.cli.outputs) is not exempt: its imports count like any other.
EXEMPT_IMPORTERS = {"bench", "bench.__main__"}
EXEMPT_PACKAGES = {"bench.cli"}

# Package cycles known and not yet untangled, each as the set of its packages, with a
# comment naming the edges that close it. None: keep it so.
ALLOWED_PACKAGE_CYCLES: list[set[str]] = []


def _package_edges() -> dict[tuple[str, str], list[str]]:
    """(importing package, imported package) -> the module imports that make the edge."""
    imports = {m: _imports(m) for m in MODULES}
    imported_from_outside = {d for m, ds in imports.items() for d in ds
                             if m not in EXEMPT_IMPORTERS
                             and _package(m) not in EXEMPT_PACKAGES}
    edges: dict[tuple[str, str], list[str]] = {}
    for m, deps in sorted(imports.items()):
        if m in EXEMPT_IMPORTERS or (_package(m) in EXEMPT_PACKAGES
                                     and m not in imported_from_outside):
            continue
        for d in sorted(deps):
            if _package(m) != _package(d):
                edges.setdefault((_package(m), _package(d)), []).append(f"{m} -> {d}")
    return edges


def _strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's strongly connected components of more than one node (the cycles)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles_between_packages():
    """The package graph (bench's subpackages, the top of bench/ as "bench", ema_contract,
    plant_rt, indie_plant) has no cycle: a module-level check misses gap -> rig -> gap
    when the modules that close it differ. Imports inside functions count."""
    edges = _package_edges()
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
    cycles = [c for c in _strongly_connected(graph) if c not in ALLOWED_PACKAGE_CYCLES]
    report = []
    for comp in cycles:
        report.append("cycle between " + ", ".join(sorted(comp)) + ":")
        report += [f"  {a} -> {b}: " + "; ".join(edges[a, b][:4])
                   + (f" (+{len(edges[a, b]) - 4})" if len(edges[a, b]) > 4 else "")
                   for a, b in sorted(edges) if a in comp and b in comp]
    assert not cycles, "\n".join(report)


BENCH_PACKAGES = sorted(f"bench.{d.name}" for d in (ROOT / "bench").iterdir()
                        if (d / "__init__.py").is_file()
                        and any(p.name != "__init__.py" for p in d.rglob("*.py")))
"""bench's subpackages of code (a package of data files only has no imports): the
pipeline's stages (sim, profiles, signals, ecu, hums, gap, rig, ...), each a node of the
package graph."""
TOP_OF_BENCH = {"__init__.py", "__main__.py"}


def loose_modules(bench_dir: Path) -> list[str]:
    """The modules at the top of `bench_dir` other than the package's entry points: each
    belongs in the subpackage of its stage (bench/sim, bench/signals, ..., bench/core for
    the small types every package shares)."""
    return sorted(p.name for p in bench_dir.glob("*.py") if p.name not in TOP_OF_BENCH)


def test_no_module_sits_loose_at_the_top_of_bench():
    loose = loose_modules(ROOT / "bench")
    assert not loose, f"modules at the top of bench/ (move them into a package): {loose}"


def test_the_loose_module_check_sees_one(tmp_path):
    for name in ("__init__.py", "__main__.py", "trace.py"):
        (tmp_path / name).write_text("")
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "loop.py").write_text("")
    assert loose_modules(tmp_path) == ["trace.py"]


def test_the_package_graph_sees_the_packages():
    """The check above cannot pass by seeing nothing: the packages are nodes, a known
    edge is in it, and a cycle through two packages is found."""
    edges = _package_edges()
    nodes = {p for e in edges for p in e}
    assert set(BENCH_PACKAGES) | {"bench", "ema_contract", "plant_rt", "indie_plant"} \
        <= nodes, sorted(set(BENCH_PACKAGES) - nodes)
    assert {f"bench.{p}" for p in ("sim", "signals", "profiles", "runtime", "core", "studies",
                                   "gap", "rig", "hums")} <= set(BENCH_PACKAGES)
    assert ("bench.rig", "bench.gap") in edges and ("bench.gap", "plant_rt") in edges
    cli = [e for (a, _), es in edges.items() if a == "bench.cli" for e in es]
    assert not [e for e in cli if e.startswith("bench.cli.gap ")], cli   # a command: exempt
    found = _strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}})
    assert found == [{"a", "b", "c"}]


def test_layers_point_one_way():
    bad = []
    for m in MODULES:
        deps = _imports(m)
        if m.startswith("plant_rt"):
            bad += [f"{m} -> {d}" for d in deps if d.startswith("bench")]
        if m.startswith("ema_contract"):
            bad += [f"{m} -> {d}" for d in deps if d.startswith(("bench", "plant_rt",
                                                                  "indie_plant"))]
        if m.startswith("indie_plant"):     # independent physics: ema_contract only
            bad += [f"{m} -> {d}" for d in deps if d.startswith(("bench", "plant_rt"))]
    assert not bad, "\n".join(bad)


INDIE_THIRD_PARTY = {"numpy", "scipy", "numba", "can", "canopen", "cantools"}


def test_indie_plant_imports_only_the_contract_and_numeric_libraries():
    """indie_plant (the blind benchmark's independent actuator) may import ema_contract, numpy, scipy,
    numba and the bus libraries ema_contract itself uses; nothing of plant_rt or bench."""
    import sys
    bad = []
    for m, path in MODULES.items():
        if not m.startswith("indie_plant"):
            continue
        for st in _nodes(_parse(_source(path))):
            names = ([a.name for a in st.names] if isinstance(st, ast.Import) else
                     [st.module or ""] if isinstance(st, ast.ImportFrom) and not st.level
                     else [])
            for name in names:
                root = name.split(".")[0]
                if root in ("indie_plant", "ema_contract", "__future__") \
                        or root in sys.stdlib_module_names or root in INDIE_THIRD_PARTY:
                    continue
                bad.append(f"{m} -> {name}")
    assert not bad, "\n".join(bad)


def test_no_module_over_600_lines():
    long = {m: n for m, p in MODULES.items()
            if (n := len(_source(p).splitlines())) > MAX_MODULE_LINES}
    assert not long, long


def _long_functions(path: Path) -> list[str]:
    src = _source(path).splitlines()
    out = []
    for node in _nodes(_parse(_source(path))):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        n = node.end_lineno - node.lineno + 1
        if n <= MAX_FUNCTION_LINES:
            continue
        body = node.body
        first = body[1] if (isinstance(body[0], ast.Expr) and isinstance(
            getattr(body[0], "value", None), ast.Constant) and len(body) > 1) else body[0]
        # the reason is a comment line between the signature/docstring and the first
        # statement
        start = (body[0].end_lineno if first is not body[0] else node.body[0].lineno - 1)
        window = src[start:first.lineno - 1] if first is not body[0] else \
            src[node.lineno:first.lineno - 1]
        if not any(line.strip().startswith("# long:") for line in window):
            out.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({n} lines)")
    return out


def test_no_function_over_80_lines_without_a_reason():
    long = [f for p in MODULES.values() for f in _long_functions(p)]
    assert not long, "\n".join(long)


@pytest.mark.parametrize("mod", ["bench.bus.logs", "bench.cli.decode"])
def test_log_decoding_needs_no_physics(mod):
    """`bench decode` and the log reader import neither numba nor the kernel (checked in a
    fresh interpreter)."""
    import subprocess
    import sys
    code = (f"import sys, importlib; importlib.import_module({mod!r}); "
            "bad = [m for m in ('numba', 'plant_rt.kernel', 'plant_rt.model') "
            "if m in sys.modules]; print(bad); raise SystemExit(1 if bad else 0)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       cwd=str(ROOT), timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr


JUDGED_CI = ("bench/hums/verdict.py", "judged_ci")
"""The one function that picks the Ci a verdict reads (harmonic, else broadband)."""


def _mentions_harmonic_ci(node: ast.AST, tainted: set[str]) -> bool:
    for n in _nodes(node):
        name = (n.id if isinstance(n, ast.Name) else n.attr if isinstance(n, ast.Attribute)
                else n.value if isinstance(n, ast.Constant) and isinstance(n.value, str)
                else n.arg if isinstance(n, ast.arg) else None)
        if name is not None and ("ci_harmonic" in name or name in tainted):
            return True
    return False


def _calls(node: ast.AST, name: str) -> list[ast.Call]:
    return [n for n in _nodes(node) if isinstance(n, ast.Call) and (
        isinstance(n.func, ast.Name) and n.func.id == name
        or isinstance(n.func, ast.Attribute) and n.func.attr == name)]


def _ci_choices(func: ast.AST) -> list[int]:
    """Lines of `func` that choose between the harmonic and the broadband Ci: an if, a
    conditional expression or a `where` whose condition asks whether the harmonic Ci (or
    a name assigned from it) is finite."""
    tainted: set[str] = set()
    for n in _nodes(func):
        if (isinstance(n, ast.Assign) and _mentions_harmonic_ci(n.value, tainted)
                and not _calls(n.value, JUDGED_CI[1])):
            tainted |= {t.id for t in n.targets if isinstance(t, ast.Name)}
    tests = [n.test for n in _nodes(func) if isinstance(n, (ast.If, ast.IfExp))]
    tests += [c.args[0] for c in _calls(func, "where") if c.args]
    return [t.lineno for t in tests
            if any(_mentions_harmonic_ci(c, tainted) for c in _calls(t, "isfinite"))]


def test_the_judged_ci_rule_is_written_once():
    """"Harmonic Ci where finite, else broadband" lives in `bench.hums.verdict.judged_ci`
    only: no other function of the tree defines it or makes that choice itself (the
    report, the watcher, the demo and the fleet status call it)."""
    where, found = [], []
    for path in MODULES.values():
        rel = path.relative_to(ROOT).as_posix()
        tree = _parse(_source(path))
        for f in _nodes(tree):
            if not isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            if (rel, f.name) == JUDGED_CI:
                found.append(rel)
                continue
            if f.name == JUDGED_CI[1]:
                where.append(f"{rel}:{f.lineno} defines another {f.name}")
            where += [f"{rel}:{ln} ({f.name}) chooses the Ci itself" for ln in _ci_choices(f)]
    assert not where, "\n".join(where)
    assert found, "judged_ci is gone"
    users = ("bench/hums/report.py", "bench/hums/live.py", "bench/cli/demo.py",
             "bench/fleet/status.py")
    assert all("judged_ci" in (ROOT / u).read_text() for u in users)


REPORTS = "bench/reports/"
SKELETON = re.compile(r"<html\b|<head\b|<!doctype", re.IGNORECASE)


def _sources_outside_reports() -> dict[str, str]:
    """Every source file of the packages outside bench/reports (modules, templates and
    pages: a skeleton may sit in a template file as well as in a string)."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*")):
            rel = path.relative_to(ROOT).as_posix()
            if (path.suffix in (".py", ".j2", ".html", ".htm", ".jinja", ".jinja2")
                    and not rel.startswith(REPORTS)):
                out[rel] = path.read_text(encoding="utf-8", errors="replace")
    return out


SOURCES = _sources_outside_reports()


def test_one_page_skeleton():
    """Every HTML page comes from bench/reports' base template: no ``<html``, ``<head``
    or doctype anywhere else in the packages (a report builds `bench.reports` blocks)."""
    own = {rel: SKELETON.search(text).group(0) for rel, text in SOURCES.items()
           if SKELETON.search(text)}
    assert not own, own


def test_one_base64_png_helper():
    """A figure becomes a base64 PNG in `bench.reports.png_base64` only: a module
    outside bench/reports that base64-encodes and saves a figure or speaks of PNG is
    writing its own (`bench.rig.update`'s base64 of compressed float arrays is data, not
    a picture)."""
    png = re.compile(r"savefig|png", re.IGNORECASE)
    own = [rel for rel, text in SOURCES.items() if rel.endswith(".py")
           and "b64encode" in text and png.search(text)]
    assert not own, own
    assert "b64encode" in (ROOT / "bench/rig/update.py").read_text()   # the check sees it


def test_the_layout_checks_see_the_sources():
    """The two checks above read the modules that once built their own pages."""
    assert {"bench/gap/report.py", "bench/fleet/report.py", "bench/rig/hums_html.py",
            "bench/hums/report.py", "bench/rig/report.py"} <= set(SOURCES)
    assert not any(rel.startswith(REPORTS) for rel in SOURCES)


UNITS_MODULE = "bench/signals/units.py"
FORCE_FACTORS = (9.80665, 4.4482216152605)       # kgf and lbf in newtons


def _bench_trees() -> list[tuple[str, ast.AST]]:
    return [(rel, _parse(_source(path))) for rel, path in
            ((p.relative_to(ROOT).as_posix(), p) for p in MODULES.values())
            if rel.startswith("bench/")]


def test_one_units_table():
    """Unit factors live in `bench.signals.units` only: no kgf/lbf factor as a number, and no
    table keyed by a force unit, in another module."""
    own = []
    for rel, tree in _bench_trees():
        if rel == UNITS_MODULE:
            continue
        for n in _nodes(tree):
            if isinstance(n, ast.Constant) and isinstance(n.value, float) \
                    and any(abs(n.value - f) < 1e-9 for f in FORCE_FACTORS):
                own.append(f"{rel}:{n.lineno}: a force unit's factor {n.value}")
            if isinstance(n, ast.Dict) and any(isinstance(k, ast.Constant)
                                               and k.value in ("kgf", "lbf") for k in n.keys):
                own.append(f"{rel}:{n.lineno}: a table keyed by force units")
    assert not own, "\n".join(own)


def test_one_thesis_row_and_one_table_writer():
    """The thesis-vs-project `Row` and its markdown table are written once, in
    `bench.core.thesis_rows`."""
    rows, writers = [], []
    for rel, tree in _bench_trees():
        for n in _nodes(tree):
            if isinstance(n, ast.ClassDef) and n.name == "Row":
                rows.append(f"{rel}:{n.lineno}")
            if isinstance(n, ast.Constant) and isinstance(n.value, str) \
                    and n.value.startswith("| id | quantity | unit | thesis"):
                writers.append(f"{rel}:{n.lineno}")
    assert len(rows) == 1 and rows[0].startswith("bench/core/thesis_rows.py:"), rows
    assert len(writers) == 1 and writers[0].startswith("bench/core/thesis_rows.py:"), writers


def test_one_table_reader():
    """A table file is opened by `bench.signals.tables` only: no other module parses CSV with
    pyarrow or opens Parquet or .npz files itself."""
    own = []
    for rel, tree in _bench_trees():
        if rel == "bench/signals/tables.py":
            continue
        for n in _nodes(tree):
            if isinstance(n, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in n.names] + [getattr(n, "module", None) or ""]
                from_pyarrow = isinstance(n, ast.ImportFrom) and n.module == "pyarrow"
                if "pyarrow.csv" in names or (from_pyarrow and "csv" in names):
                    own.append(f"{rel}:{n.lineno}: imports pyarrow.csv")
            if isinstance(n, ast.Attribute) and n.attr in ("read_table", "ParquetFile") \
                    and isinstance(n.value, ast.Name) and n.value.id == "pq":
                own.append(f"{rel}:{n.lineno}: pq.{n.attr}")
            if isinstance(n, ast.Attribute) and n.attr == "load" \
                    and isinstance(n.value, ast.Name) and n.value.id == "np":
                own.append(f"{rel}:{n.lineno}: np.load")
    assert not own, "\n".join(own)


VERDICT_MODULE = "bench/core/verdict.py"
"""The one verdict model: `Level` (the names and their one numeric code) and `Verdict`."""
LEVEL_NAMES = ("HEALTHY", "DEGRADED", "WARNING", "FAILURE", "UNKNOWN")
LEVEL_TABLE_NAMES = ("LEVELS", "LEVEL_NAMES", "LEVEL_CLASSES", "LEVEL_CODES", "VERDICTS")


def _prose(tree: ast.AST) -> set[int]:
    """ids of the string constants that are not vocabulary: docstrings, the names in
    `__all__` (an exported name such as ``UNKNOWN = "unknown"``, the usage's serial), and
    argparse metavars (``metavar="HEALTHY"``: healthy logs)."""
    out: set[int] = set()
    for n in _nodes(tree):
        if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = n.body
            out |= {id(s.value) for s in body if isinstance(s, ast.Expr)
                    and isinstance(s.value, ast.Constant)}
        if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant):
            out.add(id(n.value))        # an attribute's docstring
        if isinstance(n, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__"
                                             for t in n.targets):
            out |= {id(c) for c in ast.walk(n.value)}
        if isinstance(n, ast.keyword) and n.arg == "metavar":
            out.add(id(n.value))
    return out


def level_vocabulary(source: str) -> list[str]:
    """Where `source` writes its own verdict vocabulary: a string that is a level's name
    (``return "DEGRADED"``, ``v == "UNKNOWN"``, a list of them) or a level table assigned
    (``LEVELS = ...``, ``LEVEL_CLASSES = (...)`` as a literal). Prose naming a level
    (docstrings, help and page text) is not vocabulary."""
    tree = _parse(source)
    prose = _prose(tree)
    out = []
    for n in _nodes(tree):
        if (isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in prose
                and n.value.strip() in LEVEL_NAMES):
            out.append(f"{n.lineno}: the level name {n.value!r}")
        targets = (n.targets if isinstance(n, ast.Assign)
                   else [n.target] if isinstance(n, ast.AnnAssign) else [])
        value = getattr(n, "value", None)
        if (any(isinstance(t, ast.Name) and t.id.lstrip("_") in LEVEL_TABLE_NAMES
                for t in targets)
                and isinstance(value, (ast.List, ast.Tuple, ast.Dict, ast.Set, ast.Starred))):
            out.append(f"{n.lineno}: a level table")
    return out


def test_the_verdict_vocabulary_is_defined_once():
    """The level names and their numbers live in `bench.core.verdict` only: every other
    product module reads `Level` / `Verdict` (a module that compares with "UNKNOWN",
    returns "DEGRADED" or keeps a LEVELS list writes a second vocabulary)."""
    where = []
    for path in MODULES.values():
        rel = path.relative_to(ROOT).as_posix()
        if rel != VERDICT_MODULE:
            where += [f"{rel}:{w}" for w in level_vocabulary(_source(path))]
    assert not where, "\n".join(where)
    assert "class Level(enum.IntEnum)" in (ROOT / VERDICT_MODULE).read_text()


def test_the_vocabulary_check_sees_the_old_copies():
    """The check fails on the forms the tree had before `bench.core.verdict`: a LEVELS list,
    a returned level name, a comparison with one; prose and metavars pass."""
    old = ('UNKNOWN = "UNKNOWN"\nLEVELS = ["HEALTHY", "DEGRADED", "WARNING", "FAILURE"]\n'
           'LEVELS = (*V.LEVELS, V.UNKNOWN)\n'
           'def f(b):\n    """HEALTHY or DEGRADED."""\n'
           '    return ("DEGRADED" if b else "HEALTHY"), []\n'
           'ok = [a for a in x if a.verdict == "UNKNOWN"]\n')
    found = level_vocabulary(old)
    assert sorted(int(w.split(":")[0]) for w in found) == [1, 2, 2, 2, 2, 2, 3, 6, 6, 7], found
    fine = ('"""Levels: HEALTHY, DEGRADED."""\n__all__ = ["UNKNOWN"]\n'
            'p.add_argument("log", metavar="HEALTHY")\nx = f"last test {lv.name}: DEGRADED"\n'
            'LEVEL_CLASSES = tuple(lv.name for lv in Level)\n')
    assert level_vocabulary(fine) == []


ESTIMATORS_MODULE = "bench/signals/estimators.py"
SPECTRA = {"rfft", "fft", "amplitude_spectrum"}
MOTION_WORDS = re.compile(r"regime|dwell|moving|direction", re.IGNORECASE)
SPEED_NAMES = re.compile(r"speed|v_thr|vmax|^tol$")
ORDER_OPS = (ast.Gt, ast.Lt, ast.GtE, ast.LtE)


def _called(node: ast.AST) -> set[str]:
    return {c.func.attr if isinstance(c.func, ast.Attribute) else getattr(c.func, "id", "")
            for c in _nodes(node) if isinstance(c, ast.Call)}


def _speed_operand(node: ast.AST) -> bool:
    """|a signal| (np.abs of a name) or a name / attribute that is a speed threshold."""
    if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "abs" \
            and len(node.args) == 1 and isinstance(node.args[0], ast.Name):
        return True
    return any(SPEED_NAMES.search(n.id if isinstance(n, ast.Name) else n.attr)
               for n in _nodes(node) if isinstance(n, (ast.Name, ast.Attribute)))


def estimator_copies(source: str) -> list[str]:
    """Lines of `source` that estimate the command's fundamental or split samples into
    motion regimes themselves: a function named `fundamental_hz` / `command_frequency`,
    one that takes the argmax of a spectrum and speaks of the fundamental, or one
    speaking of regimes, dwell, motion or direction that compares a speed with a
    threshold (|v| > x, v < dwell_speed, d > tol)."""
    out = []
    for f in _nodes(_parse(source)):
        if not isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        doc = ast.get_docstring(f) or ""
        if f.name in ("fundamental_hz", "command_frequency"):
            out.append(f"{f.lineno}: {f.name}: a fundamental of its own")
        elif "argmax" in _called(f) and _called(f) & SPECTRA and re.search(
                r"fundamental|command frequency", f.name + " " + doc, re.IGNORECASE):
            out.append(f"{f.lineno}: {f.name}: the strongest spectral line, its own way")
        if MOTION_WORDS.search(f.name + " " + doc):
            for c in _nodes(f):
                if isinstance(c, ast.Compare) and any(isinstance(o, ORDER_OPS) for o in c.ops) \
                        and any(_speed_operand(x) for x in (c.left, *c.comparators)):
                    out.append(f"{c.lineno}: {f.name}: a speed against a threshold")
    return out


def test_the_fundamental_and_the_regimes_are_estimated_once():
    """The command's fundamental and the motion regimes come from `bench.signals.estimators`
    (`fundamental_hz`, `motion_regimes` / `motion_direction`) only."""
    where = []
    for path in MODULES.values():
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith("bench/") and rel != ESTIMATORS_MODULE:
            where += [f"{rel}:{w}" for w in estimator_copies(_source(path))]
    assert not where, "\n".join(where)
    src = (ROOT / ESTIMATORS_MODULE).read_text()
    assert all(f"def {f}(" in src for f in ("fundamental_hz", "motion_regimes", "noise_floor"))


def test_the_estimator_check_sees_the_old_copies():
    """The check fails on the forms the tree had before `bench.signals.estimators` held them."""
    old = ('def fundamental_hz(trace, f0):\n    return f0\n'
           'def command_frequency(trace):\n    return 1.0\n'
           'def band_f0(p):\n    """The command fundamental."""\n'
           '    a = np.abs(np.fft.rfft(p))\n    return np.argmax(a)\n'
           'def _regimes(tr):\n    moving = np.abs(v) > 0.02 * m\n    return moving\n'
           'def direction_labels(sp):\n    return np.where(d > tol, 1, np.where(d < -tol, -1, 0))\n'
           'def _speeds(self, v):\n    """Dwell, slow and fast time."""\n'
           '    dwell = fin & (v < st.dwell_speed_m_s)\n')
    found = estimator_copies(old)
    assert sorted(int(w.split(":")[0]) for w in found) == [1, 3, 5, 10, 13, 13, 16], found
    fine = ('def regimes(p):\n    """Motion regimes."""\n'
            '    edge = np.abs(t - t[k]) <= 0.2\n    return E.motion_direction(v, thr) != 0\n'
            'def peak(x):\n    """The strongest line of a residual."""\n'
            '    return np.argmax(np.fft.rfft(x))\n')
    assert estimator_copies(fine) == []


DOC_PAGES = ("docs/*.md", "README.md", "CONTRIBUTING.md")
_BRACE_GROUP = re.compile(r"\{[^{}]*\}")
TREE_PATH = re.compile(r"(?<![\w./-])((?:bench|plant_rt|ema_contract|indie_plant|tests|benchmarks"
                       r"|scripts|dbc)/[\w/{},*.-]*?\.(?:py|json|j2|css|dbc|eds|sh))(?![\w])")


def _expand(path: str) -> list[str]:
    """``bench/bus/{hub,logs}.py`` -> ``bench/bus/hub.py``, ``bench/bus/logs.py``."""
    m = _BRACE_GROUP.search(path)
    if not m:
        return [path]
    return [q for alt in m.group(0)[1:-1].split(",")
            for q in _expand(path[:m.start()] + alt + path[m.end():])]


def missing_paths(text: str, root: Path) -> list[str]:
    """The paths of the tree that `text` names (``bench/sim/loop.py``, a brace list over
    lines, a glob such as ``bench/hums/trend_*.py``) and that do not exist under `root`."""
    text = _BRACE_GROUP.sub(lambda m: re.sub(r"\s+", "", m.group(0)), text)
    out = []
    for m in TREE_PATH.finditer(text):
        for path in _expand(m.group(1)):
            found = any(root.glob(path)) if "*" in path else (root / path).exists()
            if not found:
                out.append(path)
    return out


def test_every_path_the_docs_name_exists():
    """A page naming a module by its path (docs/architecture.md's map, the equation index
    of docs/index.md, the method pages) names one that exists: a moved module cannot leave
    the docs pointing at its old place."""
    pages = sorted({p for pattern in DOC_PAGES for p in ROOT.glob(pattern)})
    assert len(pages) > 10
    where = [f"{p.relative_to(ROOT)}: {path}" for p in pages
             for path in missing_paths(p.read_text(encoding="utf-8"), ROOT)]
    assert not where, "\n".join(where)


def test_the_docs_path_check_sees_a_missing_one():
    text = ("`bench/sim/loop.py`, `bench/bus/{hub,\n  logs}.py`, `bench/hums/trend_*.py`, "
            "`bench/nowhere.py`, `bench/gap/{resim,nowhere}.py`, `bench/hums/nothing_*.py`")
    assert missing_paths(text, ROOT) == ["bench/nowhere.py", "bench/gap/nowhere.py",
                                         "bench/hums/nothing_*.py"]
