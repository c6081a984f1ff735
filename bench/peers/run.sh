#!/usr/bin/env bash
# voxd against peer voxelizers (trimesh, VTK, Open3D, libigl) on ../shared/meshes, one command:
#   bench/peers/run.sh [--voxd PATH] [--meshes a,b] [--resolutions 128,256,512] [--runs 3]
#                      [--timeout 180] [--peers trimesh,vtk,open3d,igl] [--out DIR] ...
# (all options: bench/peers/run.sh --help). The peers are pinned (bench/peers/requirements.txt)
# in a venv under ~/.cache made once and re-made when requirements.txt changes. Without --voxd it
# builds voxd (cargo build --release --locked) and uses target/release/voxd. Every cell runs
# under flock /tmp/voxd-bench.lock, so it never overlaps another benchmark that takes the lock.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)

. "$here/venv.sh"
if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  need=()
  python3 -c 'import ensurepip, venv' 2>/dev/null || need+=(python3-venv)
  ldconfig -p | grep -q 'libusb-1.0.so.0' || need+=(libusb-1.0-0) # open3d's pybind links it
  if ((${#need[@]})); then
    (apt-get update -qq || true) >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  fi
fi
peers_venv

voxd_given=0
for a in "$@"; do [[ $a == --voxd || $a == --voxd=* || $a == -h || $a == --help ]] && voxd_given=1; done
extra=()
if ((!voxd_given)); then
  (cd "$root" && cargo build --release --locked --quiet)
  extra=(--voxd "$root/target/release/voxd")
fi
exec "$VENV/bin/python" "$here/peers.py" run --meshes-dir "$root/../shared/meshes" "${extra[@]}" "$@"
