#!/usr/bin/env bash
# The Python package's tests: builds and installs isotopo (`pip install .`, Rust toolchain
# needed) in a fresh virtual environment, then runs pytest on python/tests (the real volumes
# of ../shared/data too, when that folder exists). Usage: scripts/test_python.sh [pytest args]
set -euo pipefail
cd "$(dirname "$0")/.."
venv="$(mktemp -d "${TMPDIR:-/tmp}/isotopo-venv.XXXXXX")"
trap 'rm -rf "$venv"' EXIT
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r python/tests/requirements.txt
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check .
cd python/tests
"$venv/bin/python" -m pytest -q "$@"
