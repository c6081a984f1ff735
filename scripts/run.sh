#!/usr/bin/env bash
# Builds voxd (release) and runs it. With no arguments it starts the service on 127.0.0.1:8080
# (VOXD_ADDR, VOXD_DATA_DIR and the other VOXD_* settings apply); with arguments it runs
# `voxd ARGS...`.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-vulkan.sh
cargo build --release --locked --quiet
if (($# > 0)); then
  exec ./target/release/voxd "$@"
fi
exec ./target/release/voxd serve
