#!/usr/bin/env bash
# Scaling curves: engine time against triangle count (igea decimated/subdivided, 10k..4.3M
# triangles) and against resolution (64³..2048³), for the CPU and GPU engines and the methods
# solid, surface and conservative; plus the whole `voxd voxelize` command (CPU engine, phases).
# Writes the raw outputs, results.json, tables.md and PNG plots into OUT_DIR, and the plots into
# docs/img/scaling-*.png (not with QUICK=1). See bench/scaling/README.md.
#
# Usage: bench/scaling/run.sh [OUT_DIR]      (default target/scaling/<UTC timestamp>)
# Settings (environment): VOXD (binary; default: cargo build --release, target/release/voxd),
#   RUNS=5 (timed runs per cell, after one warm-up), BIG_RUNS=3 (the same at BIG_RES),
#   TRI_RES=256,512 (grids of the triangle series), RES=64,128,256,512,1024 and BIG_RES=2048
#   (resolution series; BIG_RES runs one method per call), RES_MESH=268686 (the series mesh, by
#   triangle count), METHODS=solid,surface,conservative, WHOLE_RES=256 and WHOLE_RUNS=3 (the
#   whole-command grid and runs),
#   TIMEOUT=300 (seconds per `voxd bench` call, after the lock is taken; a call that runs over
#   is reported as "> TIMEOUT"), LOCK=/tmp/voxd-bench.lock (held over all the measurements, so
#   benchmarks that take it never overlap), SRC=../shared/meshes/igea.obj, PASSES=1 (with N > 1:
#   the whole measurement N times, reported as the lowest of the passes' medians), QUICK=1 (a
#   smoke test: tiny grids, one run, small meshes only, no docs/img).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
here=$root/bench/scaling
cd "$root"

QUICK=${QUICK:-0}
if [[ $QUICK == 1 ]]; then
  RUNS=${RUNS:-1} BIG_RUNS=${BIG_RUNS:-1} TRI_RES=${TRI_RES:-32,64} RES=${RES:-16,32}
  BIG_RES=${BIG_RES:-64} WHOLE_RES=${WHOLE_RES:-64} WHOLE_RUNS=${WHOLE_RUNS:-1} TRI_MAX=${TRI_MAX:-300000}
fi
RUNS=${RUNS:-5} BIG_RUNS=${BIG_RUNS:-3} TRI_RES=${TRI_RES:-256,512}
RES=${RES:-64,128,256,512,1024} BIG_RES=${BIG_RES:-2048} RES_MESH=${RES_MESH:-268686}
METHODS=${METHODS:-solid,surface,conservative} WHOLE_RES=${WHOLE_RES:-256} WHOLE_RUNS=${WHOLE_RUNS:-3}
TIMEOUT=${TIMEOUT:-300} LOCK=${LOCK:-/tmp/voxd-bench.lock} TRI_MAX=${TRI_MAX:-0}
SRC=${SRC:-$root/../shared/meshes/igea.obj}
CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/voxd
VENV=$CACHE/scaling-venv MESHES=$CACHE/scaling-meshes
OUT=${1:-$root/target/scaling/$(date -u +%Y%m%dT%H%M%SZ)}

built=" (VOXD given: a binary built elsewhere)"
if [[ -z ${VOXD:-} ]]; then
  cargo build --release --locked --quiet
  VOXD=$root/target/release/voxd
  built=" (built from this tree$(git diff --quiet HEAD -- src Cargo.toml Cargo.lock 2>/dev/null || echo ', with uncommitted changes'))"
fi

# PASSES=N: the whole measurement N times (OUT/pass-1 ... OUT/pass-N, each taking the lock once),
# then one report over all of them: per cell and engine the lowest of the passes' medians.
PASSES=${PASSES:-1}
if [[ $PASSES -gt 1 ]]; then
  for i in $(seq "$PASSES"); do
    echo "== pass $i of $PASSES"
    PASSES=1 NO_DOCS=1 VOXD=$VOXD "$0" "$OUT/pass-$i"
  done
  "$VENV/bin/python" "$here/report.py" --into "$OUT" "$OUT"/pass-*
  if [[ $QUICK != 1 ]]; then
    mkdir -p "$root/docs/img"
    cp "$OUT"/img/scaling-*.png "$root/docs/img/"
  fi
  echo "results: $OUT (tables.md, results.json, img/; passes in pass-*/)"
  exit 0
fi

# 1. The pinned virtual environment (rebuilt when requirements.txt changes).
if ! cmp -s "$here/requirements.txt" "$VENV/requirements.txt" 2>/dev/null; then
  rm -rf "$VENV"
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements.txt"
  cp "$here/requirements.txt" "$VENV/requirements.txt"
fi
PY=$VENV/bin/python

# 2. The meshes (cached), each checked watertight by voxd itself.
mkdir -p "$OUT/raw"
"$PY" "$here/gen_meshes.py" "$SRC" "$MESHES" >"$OUT/meshes.tsv"
tri_meshes=()
while IFS=$'\t' read -r path tris; do
  info=$("$VOXD" info "$path")
  echo "$info" >>"$OUT/meshes-info.txt"
  grep -q ', watertight,' <<<"$info" || { echo "not watertight: $info" >&2; exit 1; }
  if [[ $TRI_MAX == 0 || $tris -le $TRI_MAX ]]; then tri_meshes+=("$path"); fi
done <"$OUT/meshes.tsv"
res_mesh=$MESHES/$(basename "$SRC" .obj)-$RES_MESH.obj
[[ -f $res_mesh ]] || { echo "no mesh with $RES_MESH triangles in $MESHES" >&2; exit 1; }

# 3. The machine.
{
  echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)$built"
  echo "voxd: $VOXD ($("$VOXD" --version))"
  echo "cpu: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores"
  echo "memory: $(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo)"
  echo "kernel: $(uname -sr)"
  echo "settings: RUNS=$RUNS BIG_RUNS=$BIG_RUNS TRI_RES=$TRI_RES RES=$RES BIG_RES=$BIG_RES RES_MESH=$RES_MESH METHODS=$METHODS WHOLE_RES=$WHOLE_RES WHOLE_RUNS=$WHOLE_RUNS TIMEOUT=$TIMEOUT"
  echo "load at start: $(uptime)"
} >"$OUT/machine.txt"
cat "$OUT/machine.txt"

# One measurement, bounded by TIMEOUT: raw/NAME.txt (stdout), raw/NAME.err, raw/NAME.meta (rc,
# 1-minute load average before and after, seconds). The caller holds the lock.
measure() {
  local name=$1
  shift
  local meta=$OUT/raw/$name.meta start end rc=0
  echo "load_before: $(cut -d' ' -f1-3 /proc/loadavg)" >"$meta"
  start=$(date +%s.%N)
  timeout "$TIMEOUT" "$@" >"$OUT/raw/$name.txt" 2>"$OUT/raw/$name.err" || rc=$?
  end=$(date +%s.%N)
  {
    echo "load_after: $(cut -d' ' -f1-3 /proc/loadavg)"
    echo "run_s: $(awk "BEGIN {print $end - $start}")"
    echo "rc: $rc"
    echo "timeout_s: $TIMEOUT"
  } >>"$meta"
  printf '%-32s rc %3d  %6.1f s\n' "$name" "$rc" "$(awk "BEGIN {print $end - $start}")"
}
stem=$(basename "$SRC" .obj)
tris_of() { basename "$1" .obj | sed "s/^$stem-//"; }

# 4. Measurements: all of them under one hold of the lock (taking it once per call meant waiting
# behind other benchmarks some 25 times), so no other benchmark that takes it runs meanwhile.
exec 9>>"$LOCK"
echo "waiting for $LOCK ($(date -u +%H:%M:%SZ))"
flock 9
echo "lock taken at $(date -u +%H:%M:%SZ); load: $(uptime)" | tee -a "$OUT/machine.txt"

# 4a. Triangle series: `voxd bench`, one call per mesh and grid.
for m in "${tri_meshes[@]}"; do
  for r in ${TRI_RES//,/ }; do
    measure "tri-$(tris_of "$m")-$r" "$VOXD" bench "$m" --resolutions "$r" --methods "$METHODS" --runs "$RUNS"
  done
done

# 4b. Resolution series: one call per grid; BIG_RES one call per method, and when one runs over
# the timeout, the CPU engine alone again so that its cell is still measured.
for r in ${RES//,/ }; do
  measure "res-$r" "$VOXD" bench "$res_mesh" --resolutions "$r" --methods "$METHODS" --runs "$RUNS"
done
if [[ -n $BIG_RES ]]; then
  for meth in ${METHODS//,/ }; do
    measure "res-$BIG_RES-$meth" "$VOXD" bench "$res_mesh" --resolutions "$BIG_RES" --methods "$meth" --runs "$BIG_RUNS"
    if ! grep -q '^rc: 0$' "$OUT/raw/res-$BIG_RES-$meth.meta"; then
      measure "res-$BIG_RES-$meth-cpu" "$VOXD" bench "$res_mesh" --resolutions "$BIG_RES" --methods "$meth" --runs "$BIG_RUNS" --cpu-only
    fi
  done
fi

# 4c. The whole command, CPU engine: one warm-up and RUNS runs per mesh and method, wall clock and
# the phases of the summary line. One call per mesh.
vxl=$(mktemp --suffix=.vxl)
trap 'rm -f "$vxl"' EXIT
for m in "${tri_meshes[@]}"; do
  measure "whole-$(tris_of "$m")-$WHOLE_RES" bash -c '
    voxd=$1 mesh=$2 res=$3 runs=$4 methods=$5 out=$6
    for meth in ${methods//,/ }; do
      for i in $(seq 0 "$runs"); do
        s=$(date +%s.%N)
        line=$("$voxd" voxelize "$mesh" -o "$out" --resolution "$res" --cubic --method "$meth" --engine cpu 2>/dev/null)
        e=$(date +%s.%N)
        [[ $i == 0 ]] || echo "$meth wall $(awk "BEGIN {print $e - $s}") :: $line"
      done
    done' _ "$VOXD" "$m" "$WHOLE_RES" "$WHOLE_RUNS" "$METHODS" "$vxl"
done

echo "load at end: $(uptime)" >>"$OUT/machine.txt"
flock -u 9
exec 9>&-
tail -1 "$OUT/machine.txt"

# 5. Tables and plots.
"$PY" "$here/report.py" "$OUT"
if [[ $QUICK != 1 && -z ${NO_DOCS:-} ]]; then
  mkdir -p "$root/docs/img"
  cp "$OUT"/img/scaling-*.png "$root/docs/img/"
fi
echo "results: $OUT (tables.md, results.json, img/)"
