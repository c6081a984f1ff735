#!/usr/bin/env bash
# voxd's distance fields (--method sdf, distance) against OpenVDB, libigl, pysdf and Open3D on
# ../shared/meshes, one command:
#   bench/peers/run-distance.sh [--voxd PATH] [--meshes a,b] [--resolutions 256,512] [--big 2048]
#                               [--sample 2000] [--runs 1] [--peers openvdb,igl,pysdf,open3d] [--out DIR]
# (all options: bench/peers/run-distance.sh --help).
# Provisioning: the pinned peers venv of run.sh (requirements.txt) plus pysdf
# (requirements-distance.txt; it compiles against Eigen), and Debian's python3-openvdb for
# /usr/bin/python3 (OpenVDB's peer runs there). A peer that does not install is skipped with a
# notice. Without --voxd it builds voxd (cargo build --release --locked).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)

. "$here/venv.sh"
if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  need=()
  python3 -c 'import ensurepip, venv' 2>/dev/null || need+=(python3-venv)
  ldconfig -p | grep -q 'libusb-1.0.so.0' || need+=(libusb-1.0-0) # open3d's pybind links it
  /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null || need+=(python3-openvdb)
  [[ -e /usr/include/eigen3/Eigen/Core ]] || need+=(libeigen3-dev) # pysdf builds against it
  if ((${#need[@]})); then
    echo "installing ${need[*]} (apt)" >&2
    (apt-get update -qq || true) >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null ||
      echo "notice: apt-get install ${need[*]} failed; the peers that need them are skipped" >&2
  fi
fi
peers_venv
CPATH=/usr/include/eigen3${CPATH:+:$CPATH} peers_extra distance "$here/requirements-distance.txt" ||
  echo "notice: pysdf did not install (requirements-distance.txt); it is skipped" >&2

voxd_given=0
for a in "$@"; do [[ $a == --voxd || $a == --voxd=* || $a == -h || $a == --help ]] && voxd_given=1; done
extra=()
if ((!voxd_given)); then
  (cd "$root" && cargo build --release --locked --quiet)
  extra=(--voxd "${CARGO_TARGET_DIR:-$root/target}/release/voxd")
fi
exec "$VENV/bin/python" "$here/distance.py" run --meshes-dir "$root/../shared/meshes" "${extra[@]}" "$@"
