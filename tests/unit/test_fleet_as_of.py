"""`--as-of 9999-12-31` (a date alone is the end of that day) ended in "OverflowError:
date value out of range"; it is a one-line error naming the last date a store holds."""

from __future__ import annotations

import pytest

from bench import BenchError
from bench.fleet.status import parse_as_of


def test_the_last_day_is_beyond_the_range_in_words():
    with pytest.raises(BenchError, match="beyond the last date"):
        parse_as_of("9999-12-31")
    assert parse_as_of("9999-12-30") > parse_as_of("2026-01-01")
