"""The final check's seeds: the first check unchanged, a fresh one on seeds no other
check (nor the development generator's calibration offsets) uses."""

from __future__ import annotations

import pytest

from bench.gap import finalcheck as FC

pytestmark = pytest.mark.unit


def _noise(first: int) -> set[int]:
    b = FC.noise_base(first)
    return {b + 100 * a + j for a in range(3) for j in range(95)}


def test_the_first_check_keeps_its_seeds():
    assert FC.build_seeds() == FC.BUILD_SEEDS == (9101, 9102, 9103)
    assert FC.noise_base() == FC.NOISE_SEEDS


def test_the_fresh_check_shares_no_seed_with_the_first():
    assert not set(FC.build_seeds(FC.FRESH_SEED)) & set(FC.BUILD_SEEDS)
    assert not _noise(FC.FRESH_SEED) & _noise(FC.BUILD_SEEDS[0])
    assert min(_noise(FC.FRESH_SEED)) == 42_000
