"""Every command's --help reads as written: a description is not %-formatted by
argparse (unless it names %(prog)), so a '%%' in one reached the reader as '%%'."""

from __future__ import annotations

import argparse

import pytest

from bench.cli import build_parser

pytestmark = pytest.mark.unit


def _parsers(p: argparse.ArgumentParser, path: str = "bench"):
    yield path, p
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{path} {name}")


def test_no_doubled_percent_in_any_help():
    bad = [path for path, p in _parsers(build_parser()) if "%%" in p.format_help()]
    assert not bad, bad
