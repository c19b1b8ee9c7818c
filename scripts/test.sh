#!/usr/bin/env bash
# The README's test command: installs the project with its test extra (pytest, hypothesis,
# ruff, mypy), runs ruff and mypy, then the suite; fails if any of the three fails.
# Arguments go to pytest, e.g. `scripts/test.sh -m "not slow"`.
# The suite runs on BENCH_TEST_WORKERS pytest-xdist workers (default 2, the development
# VM's cores; 0 = one process), each test file on one worker (its module fixtures
# shared). pytest-benchmark, when installed, is switched off: it refuses xdist with a
# warning, which this suite turns into an error.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet -e '.[test]'
python -m ruff check .
python -m mypy
python -m pytest -q -p no:benchmark -n "${BENCH_TEST_WORKERS:-2}" --dist loadfile "$@"
