#!/usr/bin/env bash
# The speed guard (docs/verification.md, "The speed guard"): builds the release `kinecal`, sets
# up the numpy/scipy peer of ../shared/bench/ur10_mdh in its own virtual environment
# (target/bench-venv, the versions the stored baseline was measured with), then runs
# scripts/bench-guard.py: kinecal against the peer in one run, each figure a ratio (the peer's
# CPU time over kinecal's), failing on a drop of more than 20 % from the stored figures
# (crates/kinecal/benches/baseline.json).
#   bash scripts/bench-guard.sh            # check (exit 1 on a drop)
#   bash scripts/bench-guard.sh --update   # store this run's figures, rewrite the README's table
# Other arguments go to scripts/bench-guard.py (--rounds N, --tolerance F, --json OUT).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
if [ ! -f ../shared/bench/ur10_mdh/peer_baseline.py ]; then
    echo "bench-guard: ../shared/bench/ur10_mdh/peer_baseline.py is missing (the peer)" >&2
    exit 2
fi
venv="$root/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
# The peer's speed depends on numpy's and scipy's kernels: the baseline's versions, pinned.
"$venv/bin/python" -m pip install -q --disable-pip-version-check "numpy==2.4.6" "scipy==1.17.1"
cargo build --release -q -p kinecal-cli
export OPENBLAS_NUM_THREADS=1
exec "$venv/bin/python" scripts/bench-guard.py --kinecal "$root/target/release/kinecal" \
    --python "$venv/bin/python" "$@"
