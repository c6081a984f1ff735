#!/usr/bin/env bash
# Paired A/B of two voxd binaries under the same closed-loop load, for "what did this change
# buy" on a machine whose disk speed drifts by 10x within minutes (a shared VM):
#
#   bench/load/ab.sh OLD_BIN NEW_BIN [OUT_DIR]
#
# Both servers run at once on 127.0.0.1 (free ports, `--engine AB_ENGINE --workers AB_WORKERS`
# (cpu and 2 unless set; AB_ENGINE=gpu runs both on the GPU engine, lavapipe where there is none), each
# with its own scratch data dir on the same disk), warmed up, and idle while the other is
# measured. Then AB_ROUNDS (6) rounds, each running k6's closed loop (closed.js, AB_VUS 16
# users, `POST /v1/voxelize?resolution=64&wait=30`, AB_STEP_S 4 s) for the cube and for spot on
# A and on B, A first in odd rounds and B first in even ones, so that a drift in the machine falls on both
# alike. Prints per round jobs/s and p99 for both, and the medians and the median of the
# per-round ratios B/A. Bounded: 2 x 2 x AB_ROUNDS steps of AB_STEP_S seconds plus start-up.
# Holds the benchmark lock (/tmp/voxd-bench.lock, `LOAD_LOCK`) like run.sh. Needs what run.sh
# needs (k6 in its venv: run bench/load/run.sh once, or LOAD_VENV).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
[[ $# -ge 2 ]] || { echo "usage: $0 OLD_BIN NEW_BIN [OUT_DIR]" >&2; exit 2; }
bins=("$1" "$2")
out=${3:-$root/target/load-ab/$(date -u +%Y%m%dT%H%M%SZ)}
rounds=${AB_ROUNDS:-6}
vus=${AB_VUS:-16}
step_s=${AB_STEP_S:-4}
workers=${AB_WORKERS:-2}
engine=${AB_ENGINE:-cpu}
venv=${LOAD_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/load-venv}
k6=$venv/bin/k6
py=python3
[[ -x $k6 ]] || { echo "no k6 at $k6: run bench/load/run.sh once (it makes the venv)" >&2; exit 1; }
for b in "${bins[@]}"; do [[ -x $b ]] || { echo "not an executable: $b" >&2; exit 1; }; done
mkdir -p "$out"
lock=${LOAD_LOCK-/tmp/voxd-bench.lock}
if [[ -n $lock ]]; then
  exec 9>"$lock"
  flock -w "${LOAD_LOCK_WAIT:-1800}" 9 || { echo "gave up waiting for $lock" >&2; exit 1; }
fi
scratch=$(mktemp -d "${TMPDIR:-/tmp}/voxd-ab.XXXXXX")
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do
    for _ in $(seq 100); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$p" 2>/dev/null || true
    wait "$p" 2>/dev/null || true
  done
  rm -rf "$scratch"
}
trap cleanup EXIT
cube=$here/cube.obj
spot=$root/tests/data/spot.obj
bases=()
for i in 0 1; do
  "${bins[$i]}" serve --addr 127.0.0.1:0 --data-dir "$scratch/data$i" --engine "$engine" --workers "$workers" \
    >"$out/server$i.out" 2>"$out/server$i.err" &
  pids+=($!)
  addr=
  for _ in $(seq 100); do
    addr=$(sed -n 's|^voxd listening on http://||p' "$out/server$i.out")
    [[ -n $addr ]] && break
    sleep 0.1
  done
  [[ -n $addr ]] || { echo "server $i did not start:" >&2; cat "$out/server$i.err" >&2; exit 1; }
  bases+=("http://$addr")
  for m in "$cube" "$spot"; do
    for _ in $(seq 10); do
      curl -s -o /dev/null -X POST "http://$addr/v1/voxelize?resolution=64&wait=30" \
        -H 'Content-Type: model/obj' --data-binary @"$m"
    done
  done
done
{
  echo "A: ${bins[0]} ($(sha256sum "${bins[0]}" | cut -c1-12))"
  echo "B: ${bins[1]} ($(sha256sum "${bins[1]}" | cut -c1-12))"
  echo "$(nproc) cores, $(uname -sr), data dirs on $(df -T "$scratch" | awk 'NR == 2 {print $2}'), --engine $engine --workers $workers, $vus users, ${step_s} s steps, $rounds rounds"
  echo "start: $(uptime)"
} | tee "$out/summary.txt"
: >"$out/steps.tsv"
step() { # ROUND SERVER(0|1) MESH_NAME MESH
  local r=$1 s=$2 name=$3 m=$4 f
  f=$out/r$r-$name-${s}.json
  "$k6" run --quiet --no-color --no-usage-report --no-thresholds \
    -e BASE="${bases[$s]}" -e CLASSES="[{\"name\": \"$name\", \"mesh\": \"$m\", \"res\": 64, \"weight\": 1}]" \
    -e VUS="$vus" -e DURATION="${step_s}s" -e WAIT=30 -e SUMMARY="$f" "$here/closed.js" >/dev/null 2>"$f.err" || true
  "$py" -c '
import json, sys
d = json.load(open(sys.argv[1]))
n = d["metrics"].get("st_201", {}).get("values", {}).get("count", 0)
secs = d["state"]["testRunDurationMs"] / 1000
p = d["metrics"].get("ok_ms", {}).get("values", {})
other = sum(v["values"]["count"] for k, v in d["metrics"].items() if k.startswith("st_") and k != "st_201")
print("\t".join(map(str, [sys.argv[2], sys.argv[3], sys.argv[4], round(n / secs, 1), round(p.get("p(99)", 0), 1), other])))
' "$f" "$r" "$name" "$s" >>"$out/steps.tsv"
}
for r in $(seq "$rounds"); do
  # A first in odd rounds, B first in even ones.
  if ((r % 2)); then order="0 1"; else order="1 0"; fi
  for name in cube spot; do
    m=$cube
    [[ $name == spot ]] && m=$spot
    for s in $order; do
      step "$r" "$s" "$name" "$m"
    done
  done
  echo "round $r done: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
done
echo "end: $(uptime)" | tee -a "$out/summary.txt"
"$py" - "$out/steps.tsv" <<'EOF' | tee -a "$out/summary.txt"
import statistics as st, sys
rows = [l.split("\t") for l in open(sys.argv[1]).read().splitlines()]
print("| mesh | round | A jobs/s | B jobs/s | B/A | A p99 ms | B p99 ms | non-201 A/B |")
print("|---|---|---|---|---|---|---|---|")
for mesh in ("cube", "spot"):
    by = {}
    for r, m, s, jps, p99, other in rows:
        if m == mesh:
            by.setdefault(r, {})[s] = (float(jps), float(p99), int(other))
    ratios, a_j, b_j, a_p, b_p = [], [], [], [], []
    for r in sorted(by, key=int):
        a, b = by[r].get("0"), by[r].get("1")
        if not a or not b:
            continue
        ratio = b[0] / a[0] if a[0] else float("nan")
        ratios.append(ratio); a_j.append(a[0]); b_j.append(b[0]); a_p.append(a[1]); b_p.append(b[1])
        print(f"| {mesh} | {r} | {a[0]} | {b[0]} | {ratio:.2f} | {a[1]} | {b[1]} | {a[2]}/{b[2]} |")
    if ratios:
        print(f"| **{mesh}** | median | **{st.median(a_j):.1f}** | **{st.median(b_j):.1f}** | **{st.median(ratios):.2f}** | {st.median(a_p):.1f} | {st.median(b_p):.1f} | |")
EOF
echo "results in $out" >&2
