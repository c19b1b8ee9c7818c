#!/usr/bin/env bash
# The README's test command: installs the project with its test extra (pytest, hypothesis,
# ruff, mypy), runs ruff and mypy, then the suite; fails if any of the three fails.
# Arguments go to pytest, e.g. `scripts/test.sh -m "not slow"`.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet -e '.[test]'
python -m ruff check .
python -m mypy
python -m pytest -q "$@"
