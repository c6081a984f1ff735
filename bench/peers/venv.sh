# shellcheck shell=bash
# Sourced by the benchmark scripts (bench/peers/run*.sh, bench/colour/run.sh): the pinned peers
# venv at $VENV and its extras, each installed again only when its requirements file changes.
VENV=${VOXD_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/peers-venv}
PEERS_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)

# The venv with requirements.txt (made anew when that file changes).
peers_venv() {
  local reqs=$PEERS_DIR/requirements.txt pin
  pin=$(sha256sum "$reqs" | cut -d' ' -f1)
  if [[ ! -x $VENV/bin/python || "$(cat "$VENV/.pins" 2>/dev/null)" != "$pin" ]]; then
    echo "installing the pinned peers ($reqs) into $VENV" >&2
    rm -rf "$VENV"
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install -q --disable-pip-version-check -r "$reqs"
    echo "$pin" >"$VENV/.pins"
  fi
}

# peers_extra NAME FILE [PIP ARGS...]: FILE's requirements into the venv (status 1 when pip
# fails; the caller says what is skipped).
peers_extra() {
  local name=$1 reqs=$2 pin
  shift 2
  pin=$(sha256sum "$reqs" | cut -d' ' -f1)
  [[ "$(cat "$VENV/.pins-$name" 2>/dev/null)" == "$pin" ]] && return 0
  "$VENV/bin/pip" install -q --disable-pip-version-check "$@" -r "$reqs" || return 1
  echo "$pin" >"$VENV/.pins-$name"
}
