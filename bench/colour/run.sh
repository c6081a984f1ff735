#!/usr/bin/env bash
# The cost of colour (issue 34), one command:
#   bench/colour/run.sh [--voxd PATH] [--out DIR] [--runs 3] [--resolution 256]
# Provisioning: the pinned peers venv of bench/peers/run.sh (trimesh, Pillow) plus scikit-image
# (its bundled photograph), as bench/peers/run-mesh.sh installs them. Without --voxd it builds
# voxd (cargo build --release --locked).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
peers=$root/bench/peers
VENV=${VOXD_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/peers-venv}
PIN=$(sha256sum "$peers/requirements.txt" | cut -d' ' -f1)
if [[ ! -x $VENV/bin/python || "$(cat "$VENV/.pins" 2>/dev/null)" != "$PIN" ]]; then
  echo "installing the pinned peers ($peers/requirements.txt) into $VENV" >&2
  rm -rf "$VENV"
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q --disable-pip-version-check -r "$peers/requirements.txt"
  echo "$PIN" >"$VENV/.pins"
fi
MPIN=$(sha256sum "$peers/requirements-mesh.txt" | cut -d' ' -f1)
if [[ "$(cat "$VENV/.pins-mesh" 2>/dev/null)" != "$MPIN" ]]; then
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps -r "$peers/requirements-mesh.txt"
  echo "$MPIN" >"$VENV/.pins-mesh"
fi
args=("$@")
if [[ " $* " != *" --voxd "* ]]; then
  (cd "$root" && cargo build --release --locked --quiet)
  args+=(--voxd "${CARGO_TARGET_DIR:-$root/target}/release/voxd")
fi
if [[ " $* " != *" --out "* ]]; then
  args+=(--out "${TMPDIR:-/tmp}/voxd-bench-colour")
fi
exec "$VENV/bin/python" "$here/cost.py" "${args[@]}"
