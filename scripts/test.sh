#!/usr/bin/env bash
# The README's test command: installs the project with its test extra, then runs the suite.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet -e '.[test]'
python -m pytest -q "$@"
