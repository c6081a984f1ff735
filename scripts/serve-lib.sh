# shellcheck shell=bash
# Sourced by the check scripts that run a scratch `voxd serve` (scripts/contract.sh,
# scripts/client-check.sh): one way to start it and one way to stop it.
#
#   voxd_start TAG BIN WORK [ARGS...]   # `BIN serve --addr 127.0.0.1:0 --data-dir WORK/data ARGS`
#                                       # in its own process group (setsid), stdout WORK/out,
#                                       # stderr WORK/err, VOXD_LOG=error; waits (30 s
#                                       # at most) for its address. Sets VOXD_PGID and VOXD_URL.
#   voxd_alive TAG WHAT                 # fails the script (naming TAG) if it has stopped
#   voxd_stop                           # SIGTERM to the group, 10 s, then SIGKILL; idempotent
VOXD_PGID=
VOXD_URL=
voxd_start() {
  local tag=$1 bin=$2 work=$3
  shift 3
  VOXD_LOG=error setsid "$bin" serve --addr 127.0.0.1:0 --data-dir "$work/data" "$@" \
    >"$work/out" 2>"$work/err" &
  VOXD_PGID=$!
  for _ in $(seq 300); do
    grep -q '^voxd listening on ' "$work/out" 2>/dev/null && break
    kill -0 "$VOXD_PGID" 2>/dev/null || { cat "$work/err" >&2; echo "$tag: voxd did not start" >&2; exit 1; }
    sleep 0.1
  done
  VOXD_URL=$(sed -n 's/^voxd listening on //p' "$work/out" | head -1)
  [[ -n $VOXD_URL ]] || { echo "$tag: voxd printed no address" >&2; exit 1; }
  VOXD_WORK=$work
}
voxd_alive() {
  kill -0 "$VOXD_PGID" 2>/dev/null || { cat "$VOXD_WORK/err" >&2; echo "$1: voxd died during the run" >&2; exit 1; }
}
voxd_stop() {
  [[ -n $VOXD_PGID ]] || return 0
  kill -TERM -- "-$VOXD_PGID" 2>/dev/null || true
  for _ in $(seq 100); do kill -0 -- "-$VOXD_PGID" 2>/dev/null || break; sleep 0.1; done
  kill -KILL -- "-$VOXD_PGID" 2>/dev/null || true
  VOXD_PGID=
}
