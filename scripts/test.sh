#!/usr/bin/env bash
# The whole test suite: formatting, lints, and every test. CI runs exactly this (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

# Everything the tests need is installed first (scripts/provision.sh: Debian packages, the pinned
# venvs, a Vulkan driver, cargo-fuzz; idempotent, and it sets nothing here). What follows decides
# what is present: a check whose tools are here is required (VOXD_REQUIRE_*=1), where a missing
# tool would otherwise make it skip with a NOTICE.
./scripts/provision.sh
# Every process the suite starts from here on carries VOXD_SUITE_ID; at the end
# scripts/leftovers.sh fails the suite if one of them (voxd, nginx, redis-server, weed, ...) still runs.
eval "$(./scripts/leftovers.sh snapshot)"

# numpy + zstandard let the tests check that Python reads what voxd writes. Where they can be
# had, the Python checks are required (VOXD_REQUIRE_PYTHON=1); elsewhere they skip with a notice.
has_py() { for py in python3 /usr/bin/python3; do "$py" -c "import $1" 2>/dev/null && return 0; done; return 1; }
if has_py 'numpy, zstandard'; then export VOXD_REQUIRE_PYTHON=1; else echo "NOTICE: no python3 with numpy and zstandard; Python checks will skip"; fi
# OpenVDB reads voxd's .vdb files back (tests/vdb.rs) once python3-openvdb is installed
# (VOXD_REQUIRE_OPENVDB=1); elsewhere, and not in CI, those tests skip with a notice.
if /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null; then export VOXD_REQUIRE_OPENVDB=1; else echo "NOTICE: no pyopenvdb (python3-openvdb); OpenVDB read-back tests will skip"; fi
# The shared-queue tests (tests/redis_queue.rs) start their own redis-server (Debian's package)
# on 127.0.0.1; once it is installed they are required (VOXD_REQUIRE_REDIS=1), else they skip.
if command -v redis-server >/dev/null; then export VOXD_REQUIRE_REDIS=1; else echo "NOTICE: no redis-server; shared-queue tests will skip"; fi
# The replica topology test (tests/replicas.rs) puts Debian's nginx in front of the replicas,
# started by the test on 127.0.0.1 with its own configuration (the packaged service stays off).
if command -v nginx >/dev/null || [[ -x /usr/sbin/nginx ]]; then export VOXD_REQUIRE_NGINX=1; else echo "NOTICE: no nginx; the load-balancer test will skip"; fi
# The S3 store's tests run against SeaweedFS (`weed mini` on 127.0.0.1, started by the tests),
# from the venv provision.sh makes (VOXD_S3_VENV). Once it is there the tests are required
# (VOXD_REQUIRE_S3=1); elsewhere they skip with a notice.
S3_VENV=${VOXD_S3_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/s3-venv}
if [[ -x $S3_VENV/bin/weed ]] && "$S3_VENV/bin/weed" version >/dev/null 2>&1; then
  export PATH=$S3_VENV/bin:$PATH VOXD_REQUIRE_S3=1
else
  echo "NOTICE: no SeaweedFS (weed); the S3 store's tests will skip"
fi
# trimesh (the venv provision.sh makes, VOXD_MESH_VENV) reads the meshes `voxd mesh` and the mesh
# route write (tests/mesh_cli.rs); once it imports, those checks are required.
MESH_VENV=${VOXD_MESH_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/mesh-venv}
if "$MESH_VENV/bin/python" -c 'import trimesh' 2>/dev/null; then
  export VOXD_MESH_VENV=$MESH_VENV VOXD_REQUIRE_TRIMESH=1
else
  echo "NOTICE: no trimesh venv; the extracted meshes' trimesh checks will skip"
fi
# Headless Chromium loads the viewer page (tests/service/viewer.rs); once installed it is required.
if [[ -x /usr/bin/chromium ]]; then export VOXD_REQUIRE_CHROMIUM=1; else echo "NOTICE: no chromium; the viewer page's browser test will skip"; fi
# The native deployment test (scripts/deploy-e2e.sh: deploy/local.sh starts the compose topology
# on 127.0.0.1) runs the replicas under tini, reads the compose file with PyYAML and starts
# Debian's Prometheus (the binary only: the packaged service stays off). With tini, PyYAML,
# SeaweedFS, Redis and nginx it is required (VOXD_REQUIRE_DEPLOY=1); Prometheus is optional.
command -v prometheus >/dev/null || echo "NOTICE: no prometheus; the deployment test scrapes the replicas itself"
if command -v tini >/dev/null && has_py yaml && command -v redis-server >/dev/null && [[ ${VOXD_REQUIRE_NGINX:-} == 1 && ${VOXD_REQUIRE_S3:-} == 1 ]]; then
  export VOXD_REQUIRE_DEPLOY=1
else
  echo "NOTICE: no tini, PyYAML, Redis, nginx or SeaweedFS; the deployment test will skip"
fi

# The image check (scripts/image-check.sh) builds the Dockerfile's image with podman on a base
# made by mmdebstrap, with the binary `cargo test` built, and runs it on 127.0.0.1. With podman,
# runc and mmdebstrap it is required (VOXD_REQUIRE_IMAGE=1); elsewhere it skips with a notice.
if command -v podman >/dev/null && command -v runc >/dev/null && command -v mmdebstrap >/dev/null; then
  export VOXD_REQUIRE_IMAGE=1
else
  echo "NOTICE: no podman, runc or mmdebstrap; the image check will skip"
fi

# The GPU tests run on lavapipe where no GPU exists; once a driver is there they are required.
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
# The CPU-only build (features gpu, s3 and redis off: no wgpu, object_store or redis) must keep
# compiling: checked (type-checked, no code generated), which keeps its own copies of the
# dependencies to metadata and leaves the disk to the tests (SeaweedFS takes no writes with under
# 1% of it free).
cargo check --locked --no-default-features --all-targets --quiet
# The free space of the scratch directory and of the target directory, for a failure that
# comes from a full disk (SeaweedFS, for one, takes no writes with under 1% free).
df -h "${TMPDIR:-/tmp}" "$TARGET" | sed 's/^/disk: /'
# --show-output: skip notices (e.g. ../shared/meshes absent) stay visible. fault-injection: the
# crash test (tests/crash.rs) aborts the server inside store writes (VOXD_FAULT; inert otherwise).
cargo test --locked --features fault-injection -- --show-output
./scripts/fuzz.sh 15    # every fuzz target of fuzz/ for 15 s
# The contract check runs the binary `cargo test` built (fault injection is inert without
# VOXD_FAULT), instead of building voxd a second time without the feature.
VOXD_CONTRACT_BIN=$TARGET/debug/voxd ./scripts/contract.sh   # openapi.yaml valid, and schemathesis against the running service
VOXD_README_BIN=$TARGET/debug/voxd ./scripts/readme-check.sh   # every README session as written, its output as shown
VOXD_CLIENT_BIN=$TARGET/debug/voxd ./scripts/client-check.sh   # clients/python regenerates unchanged; it and a TypeScript client work against the running service
./scripts/deploy-check.sh  # Dockerfile, compose file and Kubernetes manifests: hadolint, compose config, schemas
./scripts/deploy-e2e.sh    # deploy/local.sh up: upload via nginx, download via the other replica, metrics, down
VOXD_IMAGE_BIN=$TARGET/debug/voxd ./scripts/image-check.sh   # the image built with podman and run: healthz, a voxelization, uid 10001 under tini, restart, graceful stop, lavapipe
./scripts/leftovers.sh check   # no process the suite started is still running
