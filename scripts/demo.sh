#!/usr/bin/env bash
# The README's first command: installs the project, then runs the bench's main job on its
# embedded defaults (no vcan, no hardware): see `bench demo --help`.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet -e .
exec bench demo "$@"
