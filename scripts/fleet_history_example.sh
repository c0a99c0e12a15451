#!/usr/bin/env bash
# Writes examples/fleet/history.json: the history of a small simulated fleet (4 GE A4 robots,
# calibrated monthly from September to December 2026), as a dump for `kinecal history import`.
#   A4-0101: link 3 shrinks by 0.006 in a month (flagged);
#   A4-0102: link 3 shrinks by 0.0008 in a month (a trend that will cross the tolerance);
#   A4-0103: joint 2's gearbox replaced on 2026-10-20 (its zero moved by 0.5 deg), stable since;
#   A4-0104: unchanged.
# Usage: bash scripts/fleet_history_example.sh [KINECAL] (default: cargo run -q -p kinecal-cli --)
set -euo pipefail
cd "$(dirname "$0")/.."
K=${1:-"cargo run -q -p kinecal-cli --"}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
db="$work/fleet.sqlite"
month=(2026-09-01 2026-10-01 2026-11-01 2026-12-01)
seed=100
for robot in A4-0101 A4-0102 A4-0103 A4-0104; do
    for m in 0 1 2 3; do
        case $robot in
        A4-0101) p14=$(python3 -c "print(-0.006 * $m)"); extra="" ;;
        A4-0102) p14=$(python3 -c "print(-0.0008 * $m)"); extra="" ;;
        A4-0103) p14=0; extra=$([ "$m" -ge 2 ] && echo ",joint2.offset=+0.5" || true) ;;
        A4-0104) p14=0; extra="" ;;
        esac
        seed=$((seed + 1))
        $K simulate --robot ge-a4 --postures 30 --seed $seed \
            --perturb "p1=+0.05,p14=$p14,joint4.slope=+0.02$extra" \
            --noise length=0.0005,angle=0.005 --out "$work/data.csv" 2>/dev/null
        $K calibrate --robot ge-a4 --data "$work/data.csv" --solution min-change \
            --weights length=0.0005,angle=0.005 --record $robot --db "$db" --at "${month[$m]}" \
            --quiet >/dev/null 2>&1
    done
done
$K history event A4-0103 --at 2026-10-20 --note "gearbox J2 replaced" --db "$db"
$K history export --format dump --db "$db" --out examples/fleet/history.json
