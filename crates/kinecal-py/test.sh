#!/usr/bin/env bash
# Builds the Python wheel of this checkout, installs it with numpy and pytest in a virtual
# environment (target/py-venv), checks the package with mypy --strict (against the native
# module's stub, and the stub against the built module with stubtest) and ruff, and runs the
# Python tests. Run from anywhere:
#   bash crates/kinecal-py/test.sh [pytest arguments]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$root/target/py-venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
# mypy, ruff and xacro (the ROS export tests expand its xacro) pinned to a major version (ruff's
# 0.x minors are its breaking releases); PyYAML reads the camera_info files back, and OpenCV is
# the cameras' reference (its 5.x wheel lacks calibrateHandEye in Python: held below 5).
"$venv/bin/python" -m pip install -q --disable-pip-version-check "maturin>=1.7,<2" numpy pytest \
    "mypy>=2,<3" "ruff>=0.17,<0.18" "jsonschema>=4.18,<5" "xacro>=2,<3" "pyyaml>=6,<7" \
    "opencv-python-headless>=4.10,<5"
rm -rf "$root/target/wheels"
# A debug build: the tests' problems are small, and it shares the test suite's artifacts.
(cd "$here" && "$venv/bin/maturin" build -q -o "$root/target/wheels")
"$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps \
    "$root"/target/wheels/kinecal-*.whl
cd "$here"
"$venv/bin/ruff" check python tests bench
"$venv/bin/python" -m mypy --strict --no-incremental python/kinecal
# The stub describes the module that was built (names, signatures, classes).
"$venv/bin/python" -m mypy.stubtest kinecal._native
"$venv/bin/python" -m pytest -q tests "$@"
