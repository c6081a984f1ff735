#!/usr/bin/env bash
# Builds voxd (release) and runs it. With no arguments it voxelizes a bundled mesh and describes
# the result; with arguments it runs `voxd ARGS...`.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-vulkan.sh
cargo build --release --locked --quiet
if (($# > 0)); then
  exec ./target/release/voxd "$@"
fi
./target/release/voxd voxelize tests/data/spot.obj -o target/spot.vxl --resolution 256
./target/release/voxd info target/spot.vxl
