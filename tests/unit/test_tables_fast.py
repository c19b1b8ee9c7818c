"""A text table reads the same through pyarrow's parser (`_arrow_delimited`, small
files) as through the line reader: the same columns, text, line numbers and errors."""

from __future__ import annotations

import lzma
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench import BenchError
from bench.signals import tables as T

CASES = {
    "plain": "a,b,c\n1,2,3\n4.5,-6e-3,7\n",
    "blank cells": "a,b\n1,\n,2\n3,4\n",
    "text column": "t,x,profile\n0,1.5,trap\n0.04,2,sine\n0.08,,trap\n",
    "blank lines": "a,b\n1,2\n\n3,4\n\n",
    "no newline at the end": "a,b\n1,2\n3,4",
    "semicolons": "a;b\n1;2\n3;4\n",
    "tabs": "a\tb\n1\t2\n3\t4\n",
    "nan and inf": "a,b\nnan,1\n2,inf\n",
    "spaced cells": "a,b\n 1, 2\n3 ,4\n",
    "underscore number": "a,b\n1_000,2\n3,4\n",
    "dates": "when,x\n2020-01-01,1\n2020-01-02,2\n",
    "bools": "flag,x\ntrue,1\nfalse,2\n",
    "mixed text and numbers": "a,b\n1,x\n2,3\n",
    "delimiter-only line": "a,b\n1,2\n,\n3,4\n",
    "quoted": 'a,b\n"1",2\n3,4\n',
    "ragged": "a,b\n1,2,3\n4,5\n",
    "spaced header": "a , b\n1,2\n",
    "twice in the header": "a,a\n1,2\n",
    "header only": "a,b\n",
    "byte-order mark": "\ufeffa,b\n1,2\n",
    "crlf": "a,b\r\n1,2\r\n",
    "big integers": "a,b\n9007199254740993,1\n-12345678901234567890,2\n",
}


def _read(path: Path, fast: bool, monkeypatch, **kw):
    with monkeypatch.context() as m:
        if not fast:
            m.setattr(T, "_arrow_delimited", lambda *a: None)
        try:
            t = T.read_table(path, **kw)
        except BenchError as exc:
            return ("error", str(exc))
    return (sorted(t.columns), [t.columns[c].tolist() for c in sorted(t.columns)],
            sorted(t.text), [list(t.text[c]) for c in sorted(t.text)], t.rows.numbers.tolist())


def _same(a, b) -> bool:
    return repr(a) == repr(b)        # NaN compares equal as text


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("kw", [{"text": True}, {}, {"finite": True},
                                {"columns": ["a"]}, {"columns": ["a"], "text": True}],
                         ids=["text", "numbers", "finite", "one column", "one column text"])
def test_the_fast_and_the_line_reader_agree(tmp_path, monkeypatch, name, kw):
    path = tmp_path / "t.csv"
    path.write_bytes(CASES[name].encode())
    assert _same(_read(path, True, monkeypatch, **kw), _read(path, False, monkeypatch, **kw))


def test_a_plain_table_takes_the_fast_path_and_a_quoted_one_does_not(tmp_path):
    plain, quoted = tmp_path / "p.csv", tmp_path / "q.csv"
    plain.write_text(CASES["text column"])
    quoted.write_text(CASES["quoted"])
    assert T._arrow_delimited(plain, ",", None, True, False) is not None
    assert T._arrow_delimited(quoted, ",", None, True, False) is None


def test_a_compressed_rig_table_agrees(tmp_path, monkeypatch):
    rows = "\n".join(f"{i * 0.04:.2f},{np.sin(i):.6f},{'trap' if i % 2 else 'sine'},20"
                     for i in range(500))
    path = tmp_path / "rig.csv.xz"
    path.write_bytes(lzma.compress(("time,current,profile,load\n" + rows + "\n").encode()))
    fast = _read(path, True, monkeypatch, text=True)
    assert fast[0] == ["current", "load", "time"] and fast[2] == ["profile"]
    assert _same(fast, _read(path, False, monkeypatch, text=True))


cell = st.one_of(st.just(""), st.just(" "), st.just("nan"), st.just("inf"), st.just("x"),
                 st.just("1_0"), st.floats(allow_nan=False, allow_infinity=False).map(repr),
                 st.integers(-10**20, 10**20).map(str))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(cell, min_size=3, max_size=3), min_size=1, max_size=6))
def test_any_grid_of_cells_reads_the_same(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("grid") / "g.csv"
    path.write_text("a,b,c\n" + "\n".join(",".join(r) for r in rows) + "\n")
    mp = pytest.MonkeyPatch()
    try:
        assert _same(_read(path, True, mp, text=True), _read(path, False, mp, text=True))
        assert _same(_read(path, True, mp), _read(path, False, mp))
    finally:
        mp.undo()
