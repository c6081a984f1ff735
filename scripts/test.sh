#!/usr/bin/env bash
# The whole test suite: formatting, lints, and every test. CI runs exactly this (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

# numpy + zstandard let the tests check that Python reads what voxd writes. Where they can be
# had, the Python checks are required (VOXD_REQUIRE_PYTHON=1); elsewhere they skip with a notice.
has_py() { for py in python3 /usr/bin/python3; do "$py" -c 'import numpy, zstandard' 2>/dev/null && return 0; done; return 1; }
if ! has_py && [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  echo "installing python3-numpy python3-zstandard for the Python checks"
  (apt-get update -qq || true) >/dev/null 2>&1
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-numpy python3-zstandard >/dev/null || true
fi
if has_py; then export VOXD_REQUIRE_PYTHON=1; else echo "NOTICE: no python3 with numpy and zstandard; Python checks will skip"; fi

# The shared-queue tests (tests/redis_queue.rs) start their own redis-server (Debian's package)
# on 127.0.0.1; once it is installed they are required (VOXD_REQUIRE_REDIS=1), else they skip.
if ! command -v redis-server >/dev/null && [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  echo "installing redis-server for the shared-queue tests"
  (apt-get update -qq || true) >/dev/null 2>&1
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq redis-server >/dev/null || true
  # Only the binary is wanted: the tests start their own servers, not the packaged service.
  (systemctl disable --now redis-server || service redis-server stop || true) >/dev/null 2>&1
fi
if command -v redis-server >/dev/null; then export VOXD_REQUIRE_REDIS=1; else echo "NOTICE: no redis-server; shared-queue tests will skip"; fi

# The GPU tests run on lavapipe where no GPU exists; once a driver is there they are required.
"$(dirname "$0")/setup-vulkan.sh"
if [[ ${CI:-} == true ]] || { compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null && ldconfig -p | grep -q libvulkan.so.1; }; then
  export VOXD_REQUIRE_GPU=1
fi
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}

cargo fmt --all -- --check
cargo clippy --locked --all-targets --quiet -- -D warnings
# --show-output: skip notices (e.g. ../shared/meshes absent) stay visible. fault-injection: the
# crash test (tests/crash.rs) aborts the server inside store writes (VOXD_FAULT; inert otherwise).
cargo test --locked --features fault-injection -- --show-output
./scripts/fuzz.sh 15    # every fuzz target of fuzz/ for 15 s (installs cargo-fuzz if missing)
./scripts/contract.sh   # openapi.yaml valid, and schemathesis against the running service
