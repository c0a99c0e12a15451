#!/usr/bin/env bash
# Throughput of `kinecal batch` on all cores against one robot after another: 200 GE A4 robots
# of 100 simulated postures each (identifiable set, 20 % held out). Prints both wall times and
# their ratio. Run from the repository root: bash scripts/batch_throughput.sh
set -euo pipefail
cargo build --release -q -p kinecal-cli
K="$PWD/target/release/kinecal"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
echo "serial,robot,data,options" > "$dir/fleet.csv"
for i in $(seq 1 200); do
  "$K" simulate --robot ge-a4 --postures 100 --seed "$i" --perturb-std length=0.01,angle=0.1 \
    --noise length=0.001,angle=0.01 --out "$dir/d$i.csv" 2>/dev/null
  echo "A4-$i,ge-a4,d$i.csv,--estimate identifiable --holdout 0.2" >> "$dir/fleet.csv"
done
t() {
  python3 -c 'import subprocess, sys, time
s = time.perf_counter()
subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
print(f"{time.perf_counter() - s:.3f}")' "$K" batch "$dir/fleet.csv" --quiet "$@"
}
all=$(t)
one=$(t --jobs 1)
python3 -c "import sys; a, o = map(float, sys.argv[1:]); print(f'200 robots x 100 postures: all cores {a:.3f} s, --jobs 1 {o:.3f} s, throughput ratio {o / a:.2f}')" "$all" "$one"
