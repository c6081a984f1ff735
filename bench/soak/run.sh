#!/usr/bin/env bash
# Soak test of `voxd serve` (on demand, not in CI): SECONDS (default 600) of mixed traffic on
# loopback from bench/soak/driver.py (with soak_client.py and soak_meshes.py: several concurrent
# clients: uploads in every format, sync and async jobs, random cancellations and deletions,
# downloads, volume operations, malformed and abandoned requests, a few large jobs), sampling
# the server's RSS, open fds, threads and store size every 5 s. Results (samples.csv,
# summary.txt, summary.json, problems.log, the server's logs) go to OUT_DIR (default
# target/soak/<timestamp> in this checkout).
#
# Usage: bench/soak/run.sh [SECONDS] [OUT_DIR]
# Environment: SOAK_CLIENTS (6), SOAK_SEED (random), SOAK_INTERVAL (5 s), SOAK_SHARED_MESHES
# (../shared/meshes; without it the large jobs use tests/data), SOAK_LARGE_JOBS=0 (leave the
# large jobs out). The server inherits the
# environment, so VOXD_* settings and e.g. MALLOC_ARENA_MAX reach it.
#
# Exit status: 0 when the driver's verdict is PASS and the server then shuts down cleanly on
# SIGTERM; 1 otherwise. The rules (driver.py, RULES): no 5xx except 503 busy (429 queue-full and
# 503 busy are the documented back-pressure and are counted apart), no connection errors, every
# malformed request answered with an allowed 4xx, no unexpected status, no bad download, the
# server alive, and after the load stops and the queue drains: fds <= warm-up fds + 16 and
# RSS <= 1.5 x the warm-up high water (VmHWM) + 64 MiB, warm-up being the first sample after
# each kind of large job has run to its end once.
set -euo pipefail

cd "$(dirname "$0")/../.."
repo=$PWD
duration=${1:-600}
target=${CARGO_TARGET_DIR:-$repo/target}
out=${2:-$repo/target/soak/$(date +%Y%m%d-%H%M%S)}
mkdir -p "$out"
out=$(cd "$out" && pwd)

echo "building voxd (release)..." >&2
cargo build --release --locked --bin voxd
bin=$target/release/voxd

data=$(mktemp -d "${TMPDIR:-/tmp}/voxd-soak.XXXXXX")
server_pid=
cleanup() {
  if [[ -n $server_pid ]] && kill -0 "$server_pid" 2>/dev/null; then
    kill -KILL "$server_pid" 2>/dev/null || true
  fi
  rm -rf "$data"
}
trap cleanup EXIT

"$bin" serve --addr 127.0.0.1:0 --data-dir "$data" --engine cpu >"$out/server.stdout" 2>"$out/server.stderr" &
server_pid=$!
addr=
for _ in $(seq 100); do
  addr=$(sed -n 's|^voxd listening on http://||p' "$out/server.stdout")
  [[ -n $addr ]] && break
  kill -0 "$server_pid" 2>/dev/null || { echo "voxd exited at start:" >&2; cat "$out/server.stderr" >&2; exit 1; }
  sleep 0.1
done
[[ -n $addr ]] || { echo "voxd did not print its address" >&2; exit 1; }
port=${addr##*:}
{
  echo "voxd $("$bin" --version 2>/dev/null || echo '?') at $addr, pid $server_pid, data dir $data"
  echo "git $(git rev-parse --short HEAD 2>/dev/null || echo '?')$(git diff --quiet 2>/dev/null || echo ' (dirty)')"
  echo "$(nproc) cores, $(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo), $(uname -sr)"
  echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee "$out/machine.txt" >&2

args=(--port "$port" --pid "$server_pid" --data-dir "$data" --out "$out" --duration "$duration"
  --clients "${SOAK_CLIENTS:-6}" --interval "${SOAK_INTERVAL:-5}" --repo "$repo")
[[ -n ${SOAK_SEED:-} ]] && args+=(--seed "$SOAK_SEED")
[[ -n ${SOAK_SHARED_MESHES:-} ]] && args+=(--shared-meshes "$SOAK_SHARED_MESHES")
[[ ${SOAK_LARGE_JOBS:-1} == 0 ]] && args+=(--no-large-jobs)

verdict=0
python3 "$repo/bench/soak/driver.py" "${args[@]}" || verdict=$?
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$out/machine.txt" >&2

# The server must still be there, and must stop cleanly on SIGTERM.
if ! kill -0 "$server_pid" 2>/dev/null; then
  echo "FAIL: the server died during the soak" >&2
  wait "$server_pid" || echo "its exit status: $?" >&2
  server_pid=
  exit 1
fi
kill -TERM "$server_pid"
stopped=0
for _ in $(seq 450); do
  kill -0 "$server_pid" 2>/dev/null || { stopped=1; break; }
  sleep 0.1
done
if [[ $stopped == 0 ]]; then
  echo "FAIL: the server did not exit within 45 s of SIGTERM" >&2
  exit 1
fi
rc=0
wait "$server_pid" || rc=$?
server_pid=
echo "server exited with status $rc after SIGTERM" | tee -a "$out/summary.txt" >&2
if [[ -s $out/server.stderr ]]; then
  echo "server stderr: $(wc -l <"$out/server.stderr") lines (in $out/server.stderr)" >&2
fi
echo "results in $out" >&2
if [[ $verdict != 0 || $rc != 0 ]]; then
  exit 1
fi
