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


def test_the_third_check_shares_no_seed_with_the_others():
    third = set(FC.build_seeds(FC.THIRD_SEED))
    assert not third & (set(FC.BUILD_SEEDS) | set(FC.build_seeds(FC.FRESH_SEED)))
    assert not _noise(FC.THIRD_SEED) & (_noise(FC.BUILD_SEEDS[0]) | _noise(FC.FRESH_SEED))
    assert min(_noise(FC.THIRD_SEED)) == 44_000


def test_the_fourth_check_shares_no_seed_with_the_others():
    earlier = (FC.BUILD_SEEDS[0], FC.FRESH_SEED, FC.THIRD_SEED)
    fourth = set(FC.build_seeds(FC.FOURTH_SEED))
    assert not fourth & set().union(*(set(FC.build_seeds(s)) for s in earlier))
    assert not _noise(FC.FOURTH_SEED) & set().union(*(_noise(s) for s in earlier))
    assert min(_noise(FC.FOURTH_SEED)) == 46_000


def test_the_fifth_check_shares_no_seed_with_the_others():
    earlier = (FC.BUILD_SEEDS[0], FC.FRESH_SEED, FC.THIRD_SEED, FC.FOURTH_SEED)
    fifth = set(FC.build_seeds(FC.FIFTH_SEED))
    assert not fifth & set().union(*(set(FC.build_seeds(s)) for s in earlier))
    assert not _noise(FC.FIFTH_SEED) & set().union(*(_noise(s) for s in earlier))
    assert min(_noise(FC.FIFTH_SEED)) == 48_000


def test_the_sixth_check_shares_no_seed_with_the_others():
    earlier = (FC.BUILD_SEEDS[0], FC.FRESH_SEED, FC.THIRD_SEED, FC.FOURTH_SEED,
               FC.FIFTH_SEED)
    sixth = set(FC.build_seeds(FC.SIXTH_SEED))
    assert not sixth & set().union(*(set(FC.build_seeds(s)) for s in earlier))
    assert not _noise(FC.SIXTH_SEED) & set().union(*(_noise(s) for s in earlier))
    assert min(_noise(FC.SIXTH_SEED)) == 50_000


def test_build_seed_is_refused_where_it_cannot_apply(capsys):
    """`--build-seed` picks the final check's builds: given with another generator it
    would be ignored (a run of other cases, exit 0), and a seed whose noise seeds fall
    below 0 cannot be drawn; both are one-line errors before any work."""
    from bench.cli import main
    assert main(["gap-bench", "--build-seed", "9301", "--cases", "1"]) == 2
    assert "--build-seed is for --generator final-check" in capsys.readouterr().err
    assert main(["gap-bench", "--generator", "final-check", "--build-seed", "10"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --build-seed") and err.count("\n") == 1, err


def test_build_seed_above_the_seed_range_is_refused(capsys):
    """A first build seed whose noise seeds pass 2**32 - 1 (what a --seed may be) is a
    one-line error before any work, not minutes of a check on seeds no other command can
    reproduce; the highest one accepted keeps every seed it draws in range."""
    from bench.cli import main
    from bench.cli.options import SEED_RANGE
    top = FC.highest_build_seed(SEED_RANGE[1])
    assert FC.noise_base(top) + FC.NOISE_SEEDS_PER_CHECK - 1 <= SEED_RANGE[1]
    assert FC.noise_base(top + 1) + FC.NOISE_SEEDS_PER_CHECK - 1 > SEED_RANGE[1]
    assert max(FC.build_seeds(top)) <= SEED_RANGE[1]
    assert main(["gap-bench", "--generator", "final-check",
                 "--build-seed", str(top + 1)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --build-seed") and err.count("\n") == 1, err
