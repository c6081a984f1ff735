#!/usr/bin/env bash
# Did the test suite leave a process running? scripts/test.sh calls it twice:
#
#   eval "$(scripts/leftovers.sh snapshot)"   # at the start: exports VOXD_SUITE_ID and _SINCE
#   scripts/leftovers.sh check                # at the end: lists what is left, fails if any
#
# `snapshot` prints shell assignments: a random suite id, which every process the suite starts
# inherits in its environment, and the time (clock ticks since boot, as /proc/PID/stat counts
# a process' start) the suite began. `check` then looks for a process
#   - whose command (/proc/PID/comm) is one of the programs the tests and deployment scripts
#     start (voxd, nginx, redis-server, weed, prometheus, tini, chromium, python, conmon;
#     LEFTOVERS_NAMES, an extended regex, replaces the list),
#   - started at or after the snapshot,
#   - and carrying this suite's id in its environment, or no usable environment at all (nginx
#     writes its process title over its environment; a child started with a cleared
#     environment has no PATH). A process with an environment without the id belongs to
#     someone else on the machine (another suite, a developer) and is not counted.
# It waits up to LEFTOVERS_WAIT seconds (default 15: watchdogs poll once a second, a SIGKILLed
# process needs reaping) for such processes to end, then prints each one still alive
# (ps -o pid,ppid,lstart,user,args) and exits 1. Zombies run nothing and are not counted.
# LEFTOVERS_KILL=1 also SIGKILLs what it found (after listing it), so a failed run does not
# leave them to the next one.
set -euo pipefail

NAMES=${LEFTOVERS_NAMES:-'voxd|nginx|redis-server|weed|prometheus|tini|chromium|chrome|headless_shell|python3?(\.[0-9]+)?|conmon'}

now_ticks() {
  local up
  read -r up _ </proc/uptime
  awk -v u="$up" -v hz="$(getconf CLK_TCK)" 'BEGIN { printf "%d\n", u * hz }'
}

# PID -> "STATE STARTTIME" from /proc/PID/stat (the command may hold spaces and parentheses).
proc_stat() {
  local stat
  stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 1
  stat=${stat##*) }
  # shellcheck disable=SC2086
  set -- $stat
  echo "$1 ${20}"
}

# The suite's candidates still alive, one pid a line.
found() {
  local p pid comm st ticks env
  for p in /proc/[0-9]*; do
    pid=${p#/proc/}
    comm=$(cat "$p/comm" 2>/dev/null) || continue
    [[ $comm =~ ^($NAMES)$ ]] || continue
    read -r st ticks <<<"$(proc_stat "$pid")" || continue
    [[ -n ${ticks:-} && $st != [ZX] ]] || continue
    ((ticks >= VOXD_SUITE_SINCE)) || continue
    env=$( { tr "\0" "\n" <"$p/environ"; } 2>/dev/null) || env=
    if grep -qx "VOXD_SUITE_ID=$VOXD_SUITE_ID" <<<"$env" || ! grep -q '^PATH=' <<<"$env"; then
      echo "$pid"
    fi
  done
}

case ${1:-} in
snapshot)
  id=$(od -An -N8 -tx1 /dev/urandom | tr -d ' \n')
  printf 'export VOXD_SUITE_ID=%s VOXD_SUITE_SINCE=%s\n' "$id" "$(now_ticks)"
  ;;
check)
  : "${VOXD_SUITE_ID:?run eval \"\$($0 snapshot)\" first}" "${VOXD_SUITE_SINCE:?}"
  end=$((SECONDS + ${LEFTOVERS_WAIT:-15}))
  while :; do
    mapfile -t left < <(found)
    ((${#left[@]} == 0 || SECONDS >= end)) && break
    sleep 0.5
  done
  if ((${#left[@]} == 0)); then
    echo "leftovers: no process the suite started is still running"
    exit 0
  fi
  echo "leftovers: FAIL: ${#left[@]} process(es) the suite started are still running:" >&2
  ps -o pid,ppid,pgid,lstart,user,args -p "$(IFS=,; echo "${left[*]}")" >&2 || true
  if [[ ${LEFTOVERS_KILL:-0} == 1 ]]; then
    kill -KILL "${left[@]}" 2>/dev/null || true
    echo "leftovers: SIGKILLed them (LEFTOVERS_KILL=1)" >&2
  fi
  exit 1
  ;;
*)
  echo "usage: $0 snapshot | check   (see the comment at the top)" >&2
  exit 2
  ;;
esac
