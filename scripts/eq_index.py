"""The equation index: each thesis equation cited in the product code (``# eq. 5.21``,
``eqs. 5.27-5.28``) and the functions that cite it, as a markdown table.

    python scripts/eq_index.py                    # print the table
    python scripts/eq_index.py --write docs/index.md

``--write`` replaces the text between the ``<!-- eq-index:begin -->`` and
``<!-- eq-index:end -->`` markers of the given file and leaves the rest as it is.
``--check`` exits 1 when the file's table differs from the code's (the docs test uses it).
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("plant_rt", "bench", "ema_contract", "indie_plant")
BEGIN, END = "<!-- eq-index:begin -->", "<!-- eq-index:end -->"
_NUM = r"\d+\.\d+"
_CITE = re.compile(rf"\beqs?\.\s*({_NUM}[a-z]?(?:\s*(?:[-/,]|and|to|or)\s*(?:eq\.\s*)?{_NUM}[a-z]?)*)",
                   re.IGNORECASE)
_RANGE = re.compile(rf"({_NUM})\s*(?:-|to)\s*({_NUM})")


def _numbers(cited: str) -> list[str]:
    """'5.27-5.29' -> 5.27, 5.28, 5.29 (a range within one chapter); '5.21/5.27' -> both."""
    out: list[str] = []
    for a, b in _RANGE.findall(cited):
        (ca, na), (cb, nb) = a.split("."), b.split(".")
        if ca == cb and int(na) < int(nb) <= int(na) + 40:
            out += [f"{ca}.{k}" for k in range(int(na), int(nb) + 1)]
    out += re.findall(_NUM, cited)
    return out


def _scopes(tree: ast.Module) -> list[tuple[int, int, str]]:
    """(first line, last line, qualified name) of every def and class, outer first."""
    found: list[tuple[int, int, str]] = []

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                found.append((first, child.end_lineno or child.lineno, name))
                walk(child, name + ".")
            else:
                walk(child, prefix)

    walk(tree, "")
    return found


def _where(scopes: list[tuple[int, int, str]], line: int) -> str:
    inner = [s for s in scopes if s[0] <= line <= s[1]]
    return max(inner, key=lambda s: s[0])[2] if inner else "(module)"


def collect(root: Path = ROOT) -> dict[str, set[str]]:
    """Equation number -> {'path::function'} over the product packages."""
    index: dict[str, set[str]] = defaultdict(set)
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            text = path.read_text(encoding="utf-8")
            scopes = _scopes(ast.parse(text))
            rel = path.relative_to(root).as_posix()
            for lineno, line in enumerate(text.splitlines(), 1):
                for m in _CITE.finditer(line):
                    for eq in _numbers(m.group(1)):
                        index[eq].add(f"{rel}::{_where(scopes, lineno)}")
    return index


def _key(eq: str) -> tuple[int, int]:
    chapter, number = eq.split(".")
    return int(chapter), int(number)


def _place_key(place: str) -> tuple[int, str]:
    """The plant (which implements the physics) first, then the contract, indie_plant, bench."""
    return PACKAGES.index(place.split("/", 1)[0]), place


def table(index: dict[str, set[str]]) -> str:
    rows = ["| eq. | file::function |", "|---|---|"]
    for eq in sorted(index, key=_key):
        places = ", ".join(f"`{p}`" for p in sorted(index[eq], key=_place_key))
        rows.append(f"| {eq} | {places} |")
    return "\n".join(rows) + "\n"


def replaced(doc: str, body: str) -> str:
    head, sep, rest = doc.partition(BEGIN)
    _, sep2, tail = rest.partition(END)
    if not sep or not sep2:
        raise ValueError(f"the markers {BEGIN} and {END} are missing")
    return f"{head}{BEGIN}\n{body}{END}{tail}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", type=Path, help="markdown file whose marked table to replace")
    ap.add_argument("--check", type=Path, help="exit 1 if this file's table is out of date")
    args = ap.parse_args(argv)
    body = table(collect())
    target = args.write or args.check
    if target is None:
        sys.stdout.write(body)
        return 0
    try:
        doc = target.read_text(encoding="utf-8")
        new = replaced(doc, body)
    except (OSError, ValueError) as exc:
        print(f"error: {target}: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if new != doc:
            print(f"{target}: the equation index is out of date; "
                  f"run python scripts/eq_index.py --write {target}", file=sys.stderr)
            return 1
        return 0
    target.write_text(new, encoding="utf-8")
    print(f"{target}: {len(body.splitlines()) - 2} equations")
    return 0


if __name__ == "__main__":
    sys.exit(main())
