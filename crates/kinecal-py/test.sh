#!/usr/bin/env bash
# Builds the Python wheel of this checkout, installs it with numpy and pytest in a virtual
# environment (target/py-venv), and runs the Python tests. Run from anywhere:
#   bash crates/kinecal-py/test.sh [pytest arguments]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$root/target/py-venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check "maturin>=1.7,<2" numpy pytest
rm -rf "$root/target/wheels"
# A debug build: the tests' problems are small, and it shares the test suite's artifacts.
(cd "$here" && "$venv/bin/maturin" build -q -o "$root/target/wheels")
"$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps \
    "$root"/target/wheels/kinecal-*.whl
cd "$here" && "$venv/bin/python" -m pytest -q tests "$@"
