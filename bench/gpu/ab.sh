#!/usr/bin/env bash
# Paired A/B of the GPU engine's small-job throughput: two builds of examples/gpu_small_jobs
# (e.g. before and after a change; the example uses only the engine's public API, so it builds
# against any revision), run interleaved on the same cases, A first in odd rounds and B first
# in even ones. Prints each run's jobs/s, then per case the medians and the median of the
# per-round ratios B/A.
#
#   bench/gpu/ab.sh OLD_EXAMPLE NEW_EXAMPLE
#
# GPU_AB_ROUNDS (5) rounds; the cases are GPU_AB_CASES (mesh:resolution:jobs:threads, space
# separated). Bounded: rounds x cases x 2 runs of a few seconds each. VOXD_ADAPTER picks the
# adapter (lavapipe where there is no GPU).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
[[ $# -eq 2 ]] || { echo "usage: $0 OLD_EXAMPLE NEW_EXAMPLE" >&2; exit 2; }
bins=("$1" "$2")
for b in "${bins[@]}"; do [[ -x $b ]] || { echo "not an executable: $b" >&2; exit 1; }; done
rounds=${GPU_AB_ROUNDS:-5}
cases=${GPU_AB_CASES:-"bench/load/cube.obj:64:400:1 bench/load/cube.obj:64:400:4 tests/data/spot.obj:64:400:1 tests/data/spot.obj:64:400:4 tests/data/spot.obj:128:200:4"}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
results=$(mktemp)
trap 'rm -f "$results"' EXIT
cd "$root"
for r in $(seq "$rounds"); do
  order=(0 1); (( r % 2 == 0 )) && order=(1 0)
  for c in $cases; do
    IFS=: read -r mesh n jobs threads <<<"$c"
    for i in "${order[@]}"; do
      line=$("${bins[$i]}" "$mesh" "$n" "$jobs" "$threads")
      rate=$(sed -n 's/.*: gpu \([0-9.]*\) jobs\/s.*/\1/p' <<<"$line")
      echo "round $r $( ((i)) && echo B || echo A ) $c gpu $rate jobs/s"
      echo "$r $i $c $rate" >>"$results"
    done
  done
done
python3 - "$results" <<'PY'
import sys, statistics as st, collections
runs = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    r, i, c, rate = line.split()
    runs[c].setdefault(r, {})[int(i)] = float(rate)
print("\n| case (mesh:n:jobs:threads) | A jobs/s (median) | B jobs/s (median) | B/A (median of rounds) |")
print("|---|---|---|---|")
for c, by_round in runs.items():
    a = [v[0] for v in by_round.values()]; b = [v[1] for v in by_round.values()]
    ratio = st.median(v[1] / v[0] for v in by_round.values())
    print(f"| {c} | {st.median(a):.0f} | {st.median(b):.0f} | {ratio:.2f} |")
PY
