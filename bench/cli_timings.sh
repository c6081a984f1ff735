#!/usr/bin/env bash
# Median of N runs of `voxd voxelize` (whole command, wall clock) and of the phases the summary
# line reports. Usage: bench/cli_timings.sh MESH RESOLUTION [RUNS=5] [extra voxd args...]
set -euo pipefail
cd "$(dirname "$0")/.."
mesh=$1 res=$2 runs=${3:-5}
shift $(($# < 3 ? $# : 3))
cargo build --release --locked --quiet
out=$(mktemp --suffix=.vxl)
trap 'rm -f "$out"' EXIT
rows=()
for _ in $(seq "$runs"); do
  start=$(date +%s.%N)
  line=$(./target/release/voxd voxelize "$mesh" -o "$out" --resolution "$res" --cubic "$@" 2>/dev/null)
  end=$(date +%s.%N)
  phases=$(sed -E 's/.*\(load ([0-9.]+), diagnose ([0-9.]+), voxelize ([0-9.]+), write ([0-9.]+)\).*/\1 \2 \3 \4/' <<<"$line")
  rows+=("$start $end $phases")
done
printf '%s\n' "${rows[@]}" | python3 -c '
import sys, statistics as st
rows = [list(map(float, l.split())) for l in sys.stdin if l.strip()]
rows = [[r[1] - r[0]] + r[2:] for r in rows]
names = ["whole command", "load (read+gunzip+parse)", "diagnose", "voxelize (snap+engine)", "write"]
meds = [st.median(c) for c in zip(*rows)]
for n, m in zip(names, meds):
    print(f"{n:26s} {m*1000:8.1f} ms  ({100*m/meds[0]:5.1f}%)")
' 
echo "($runs runs, $(nproc) cores, $(uname -m))"
