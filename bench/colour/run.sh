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
. "$peers/venv.sh"
peers_venv
peers_extra mesh "$peers/requirements-mesh.txt" --no-deps
args=("$@")
if [[ " $* " != *" --voxd "* ]]; then
  (cd "$root" && cargo build --release --locked --quiet)
  args+=(--voxd "${CARGO_TARGET_DIR:-$root/target}/release/voxd")
fi
if [[ " $* " != *" --out "* ]]; then
  args+=(--out "${TMPDIR:-/tmp}/voxd-bench-colour")
fi
exec "$VENV/bin/python" "$here/cost.py" "${args[@]}"
