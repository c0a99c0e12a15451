#!/usr/bin/env bash
# The README's two commands as a newcomer meets them: a clean clone of this repository's HEAD in
# a temporary folder, `../shared` linked beside it, then `cargo run -p kinecal-cli -- demo`
# and `cargo test --workspace`, each timed (wall clock, CPU, peak memory), with how many crates
# each compiled and the size of `target/` at the end. Run it on an idle machine: the figures
# are what the README quotes. Nothing outside the temporary folder is touched; it is removed
# at the end unless KEEP=1.
#
#   bash scripts/first-run.sh            # prints the figures
set -euo pipefail
[ -x /usr/bin/time ] || { echo "first-run: needs /usr/bin/time (Debian: apt-get install time)" >&2; exit 1; }
repo=$(cd "$(dirname "$0")/.." && pwd)
if [ ! -d "$repo/../shared" ]; then
    echo "first-run: no ../shared beside the repository ($repo/../shared): the tests need its real data" >&2
    exit 1
fi
shared=$(cd "$repo/../shared" && pwd)
work=$(mktemp -d /tmp/kinecal-first-run.XXXXXX)
[ "${KEEP:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT
git clone -q "$repo" "$work/kinecal"
ln -s "$shared" "$work/shared"
cd "$work/kinecal"
# A newcomer's shell: no CI switches, no test database, no shared build folder.
unset CI KINECAL_TEST_PG KINECAL_TEST_PG_DIR CARGO_TARGET_DIR CARGO_INCREMENTAL
step() {
    local name=$1
    shift
    local status=0
    /usr/bin/time -f "%e %U %S %M" -o "$work/$name.time" "$@" >"$work/$name.out" 2>"$work/$name.err" \
        || status=$?
    read -r wall user sys peak < <(tail -n 1 "$work/$name.time")
    local crates
    crates=$(grep -c '^ *Compiling ' "$work/$name.err" || true)
    awk -v n="$name" -v s="$status" -v w="$wall" -v u="$user" -v y="$sys" -v p="$peak" -v c="$crates" \
        'BEGIN { printf "%-5s exit %d: %d min %02d s wall, %.0f s CPU, %.0f MB peak, %d crates compiled\n",
                 n, s, int(w / 60), int(w) % 60, u + y, p / 1024, c }'
    return "$status"
}
step run cargo run -p kinecal-cli -- demo
step test cargo test --workspace
echo "target/: $(du -sh target | cut -f1)"
