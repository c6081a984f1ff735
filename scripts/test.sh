#!/usr/bin/env bash
# The whole test suite: formatting, lints, and every test. CI runs exactly this (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

# numpy + zstandard let the tests check that Python reads what voxd writes (they skip, with a
# notice, where these cannot be installed).
if ! python3 -c 'import numpy, zstandard' 2>/dev/null; then
  if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
    echo "installing python3-numpy python3-zstandard for the Python checks"
    (apt-get update -qq || true) >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-numpy python3-zstandard >/dev/null || echo "could not install them; Python checks will be skipped"
  fi
fi

cargo fmt --all -- --check
cargo clippy --locked --all-targets --quiet -- -D warnings
cargo test --locked
