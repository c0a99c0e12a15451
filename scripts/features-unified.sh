#!/usr/bin/env bash
# Lists the crates whose features differ between `cargo run -p kinecal-cli` and
# `cargo test --workspace`: each such crate (and all above it) would be built twice by the
# README's two commands. Exit 1 when there is any. See crates/workspace-hack/Cargo.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
run=$(cargo tree -p kinecal-cli -e normal,build -f '{p} {f}' --prefix none | sed 's/ (\*)$//' | sort -u)
test=$(cargo tree --workspace -e normal,build,dev -f '{p} {f}' --prefix none | sed 's/ (\*)$//' | sort -u)
diff=$(python3 - "$run" "$test" <<'PY'
import sys
def load(text):
    d = {}
    for line in text.splitlines():
        parts = line.split(" ")
        d.setdefault(" ".join(parts[:2]), set()).add(" ".join(parts[2:]))
    return d
run, test = load(sys.argv[1]), load(sys.argv[2])
for name in sorted(run):
    if name in test and run[name] != test[name]:
        print(f"{name}: run {sorted(run[name])} test {sorted(test[name])}")
PY
)
if [ -n "$diff" ]; then
    echo "features differ between the README's two commands (add them to crates/workspace-hack):"
    echo "$diff"
    exit 1
fi
echo "the README's two commands resolve the same features"
