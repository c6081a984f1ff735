#!/usr/bin/env bash
# Meshes out of volumes (issue 33): voxd mesh (cubes, surface-nets) against OpenVDB's
# convertToPolygons, scikit-image's marching_cubes and trimesh's VoxelGrid on the same volumes,
# one command:
#   bench/peers/run-mesh.sh [--voxd PATH] [--meshes a,b] [--resolutions 256,512] [--out DIR]
# (all options: bench/peers/run-mesh.sh --help). Provisioning: the pinned peers venv of run.sh
# (requirements.txt) plus scikit-image (requirements-mesh.txt), and Debian's python3-openvdb for
# /usr/bin/python3 (OpenVDB's peer runs there). A peer that does not install is skipped with a
# notice. Without --voxd it builds voxd (cargo build --release --locked).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)

. "$here/venv.sh"
if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  need=()
  python3 -c 'import ensurepip, venv' 2>/dev/null || need+=(python3-venv)
  /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null || need+=(python3-openvdb)
  if ((${#need[@]})); then
    echo "installing ${need[*]} (apt)" >&2
    (apt-get update -qq || true) >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null ||
      echo "notice: apt-get install ${need[*]} failed; the peers that need them are skipped" >&2
  fi
fi
peers_venv
peers_extra mesh "$here/requirements-mesh.txt" --no-deps ||
  echo "notice: scikit-image did not install (requirements-mesh.txt); it is skipped" >&2

voxd_given=0
for a in "$@"; do [[ $a == --voxd || $a == --voxd=* || $a == -h || $a == --help ]] && voxd_given=1; done
extra=()
if ((!voxd_given)); then
  (cd "$root" && cargo build --release --locked --quiet)
  extra=(--voxd "${CARGO_TARGET_DIR:-$root/target}/release/voxd")
fi
exec "$VENV/bin/python" "$here/mesh.py" run --meshes-dir "$root/../shared/meshes" "${extra[@]}" "$@"
