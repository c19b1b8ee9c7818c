"""The docs are product docs: no page over 800 lines, no history words ("session N",
"issue N", "variant N", dated work logs) in the docs, the product code, the tests, the
benchmarks or the scripts (history lives in git and CHANGELOG.md), and the equation
index of docs/index.md matches the code's ``eq. N.M`` citations."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MAX_PAGE_LINES = 800
SCANNED = ("docs", "bench", "plant_rt", "indie_plant", "ema_contract", "tests",
           "benchmarks", "scripts")
SUFFIXES = (".md", ".py", ".sh")
_DATE = r"20\d\d-\d\d-\d\d"
HISTORY = re.compile(
    r"\bsessions?\s+\d+"
    r"|\bissues?\s+\d+|\bissue's\b"
    r"|\bvariants?\s+(?:\d+|[A-Z])\b"
    rf"|\(\s*{_DATE}\s*\)"
    rf"|\b(?:since|before|measured|checked|re-measured)\s+{_DATE}",
    re.IGNORECASE)
# the rule's own statement names what it forbids
EXEMPT = {"tests/unit/test_docs.py", "CONTRIBUTING.md"}


def _files() -> list[Path]:
    out = []
    for top in SCANNED:
        for path in sorted((ROOT / top).rglob("*")):
            rel = path.relative_to(ROOT).as_posix()
            if path.suffix in SUFFIXES and path.is_file() and rel not in EXEMPT \
                    and "__pycache__" not in path.parts:
                out.append(path)
    return out


def history_lines(paths: list[Path]) -> list[str]:
    found = []
    for path in paths:
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            m = HISTORY.search(line)
            if m:
                found.append(f"{path.relative_to(ROOT)}:{n}: {m.group(0)!r}")
    return found


def test_no_docs_page_over_800_lines():
    long = {p.name: n for p in sorted((ROOT / "docs").glob("*.md"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_PAGE_LINES}
    assert not long, f"docs pages over {MAX_PAGE_LINES} lines (split them): {long}"


def test_no_history_words_in_docs_code_or_tests():
    found = history_lines(_files())
    assert not found, ("history words (say the thing itself; history goes to git and "
                       "CHANGELOG.md):\n" + "\n".join(found[:60])
                       + (f"\n... and {len(found) - 60} more" if len(found) > 60 else ""))


@pytest.mark.parametrize("text", [
    "as session 19 measured", "the issue's split", "issue 11", "variant 3 of the features",
    "Results of variant B", "Start-up (2026-11-24)", "before 2026-11-24 a cycle",
    "measured 2026-11-23"])
def test_the_history_rule_catches(text):
    assert HISTORY.search(text)


@pytest.mark.parametrize("text", [
    "with session(2):", "the new session is not throttled", "RUL as of 2024-06-28",
    '"--as-of", "2026-01-06"', "ISO dates (2024-03-01, 2024-03-01T08:00)",
    "the variant with two nuts"])
def test_the_history_rule_lets_through(text):
    assert not HISTORY.search(text)


def _eq_index():
    spec = importlib.util.spec_from_file_location("eq_index", ROOT / "scripts" / "eq_index.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_equation_index_is_current():
    mod = _eq_index()
    doc = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    assert mod.replaced(doc, mod.table(mod.collect())) == doc, \
        "docs/index.md's equation index is out of date: python scripts/eq_index.py --write docs/index.md"


def test_the_equation_index_finds_ranges_and_functions(tmp_path):
    mod = _eq_index()
    pkg = tmp_path / "plant_rt"
    pkg.mkdir()
    (pkg / "m.py").write_text('"""Module (eq. 5.1)."""\n\n\nclass C:\n    def f(self):\n'
                              '        return 1  # eqs. 5.27-5.29\n\n\ndef g():\n'
                              '    """Contacts, eq. 5.21/5.26."""\n')
    index = mod.collect(tmp_path)
    assert index["5.1"] == {"plant_rt/m.py::(module)"}
    assert index["5.28"] == {"plant_rt/m.py::C.f"}
    assert index["5.21"] == index["5.26"] == {"plant_rt/m.py::g"}
