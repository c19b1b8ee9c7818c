"""Rows of thesis vs project values: ratios, the >10 % reason check, markdown, doc sections."""

from __future__ import annotations

import math

import pytest

from bench import BenchError
from bench.core.thesis_rows import Row, check, markdown
from bench.hums.table import replace_section


def test_ratio_and_reason_check():
    assert Row("H2", "Cp - 1", "%", 8.4, 7.0).ratio == pytest.approx(7.0 / 8.4)
    assert math.isnan(Row("H5", "line", "A", "slightly above 1", 1.08).ratio)
    rows = [Row("H2", "a", "%", 8.4, 7.0), Row("H3", "b", "%", 7.8, 7.5),
            Row("H4", "c", "-", 2.7, 1.1, why="start-up peaks")]
    assert check(rows) == ["H2"]


def test_markdown_escapes_pipes():
    text = markdown([Row("H2", "mean error |e|", "um", 77.0, 66.6, "a|b")])
    line = text.splitlines()[-1]
    assert line.count(" | ") == 6 and "\\|e\\|" in line and "a\\|b" in line


def test_replace_section(tmp_path):
    p = tmp_path / "doc.md"
    p.write_text("# Doc\n\nintro\n\n<!-- s:begin -->\nold\n<!-- s:end -->\n\nafter\n")
    replace_section(p, "s", "new body")
    text = p.read_text()
    assert "new body" in text and "old" not in text and text.endswith("after\n")
    replace_section(p, "t", "appended")
    assert p.read_text().rstrip().endswith("<!-- t:end -->")
    p.write_text("<!-- u:begin -->\n")
    with pytest.raises(BenchError, match="unbalanced"):
        replace_section(p, "u", "x")
