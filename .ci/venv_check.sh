#!/usr/bin/env bash
# The CI job after the suite: the README's way in a virtual environment. A fresh venv (no
# system site-packages), the project installed into it with `pip install '.[test]'` (not
# editable), then inside it the wheel test (which builds its own venv from this one) and
# the README's bus session as written (.ci/readme_session.py), each in a fresh folder with
# its own state directory. A venv once failed the wheel test while CI, on the system
# Python, passed: this job is there so that it cannot come back unseen.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python -m venv "$tmp/venv"
# shellcheck disable=SC1091
. "$tmp/venv/bin/activate"
python -m pip install --quiet "$root[test]"
export BENCH_STATE_DIR="$tmp/state"
unset PYTHONPATH
python -m pytest -q -p no:benchmark -n 0 tests/system/test_wheel.py
python .ci/readme_session.py --work "$tmp/session"
