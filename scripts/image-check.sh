#!/usr/bin/env bash
# Builds the container image from the Dockerfile and runs it, with podman (no Docker engine
# needed): the base image debian:bookworm-slim made here by mmdebstrap (once, then cached in
# podman's storage), the runtime image from the Dockerfile with a binary built outside
# (VOXD_BIN_STAGE=prebuilt: crates cannot be fetched inside a build), then, through a port
# published on 127.0.0.1 and a named volume on /data: /healthz, a voxelization, the process
# tree (tini as PID 1, voxd as uid 10001), the volume after `podman restart`, the image's
# HEALTHCHECK, `podman stop` (graceful SIGTERM through tini: exit code 0, within the grace
# period), and a second container with VOXD_ENGINE=gpu on lavapipe.
#   VOXD_IMAGE_BIN=target/debug/voxd ./scripts/image-check.sh
# VOXD_IMAGE_BIN: the binary (default ${CARGO_TARGET_DIR:-target}/debug/voxd), dynamically
# linked for Debian 12. Where podman cannot run containers (not installed, or a trivial
# `podman run --runtime runc` fails) it skips with a NOTICE, unless VOXD_REQUIRE_IMAGE=1.
# Containers use runc (crun fails on hybrid cgroups) and explicit --ulimit values (podman's
# defaults try to raise limits, which some hosts refuse). Everything started here is removed on
# exit; the images (the base and localhost/voxd:image-check) stay cached.
set -euo pipefail
cd "$(dirname "$0")/.."

BIN=${VOXD_IMAGE_BIN:-${CARGO_TARGET_DIR:-target}/debug/voxd}
BASE=debian:bookworm-slim # the Dockerfile's runtime base
IMAGE=localhost/voxd:image-check
GRACE=40 # podman stop -t
START=$SECONDS

skip() {
  if [[ ${VOXD_REQUIRE_IMAGE:-} == 1 ]]; then
    echo "image-check: $1 (VOXD_REQUIRE_IMAGE=1)" >&2
    exit 1
  fi
  echo "NOTICE: $1; skipping the image check"
  exit 0
}
fail() { echo "image-check: FAILED: $*" >&2; exit 1; }
step() { echo "== $*"; }

command -v podman >/dev/null || skip "no podman (apt-get install podman runc mmdebstrap)"
command -v runc >/dev/null || skip "no runc (apt-get install runc)"
[[ -x $BIN ]] || fail "no binary at $BIN (VOXD_IMAGE_BIN)"

# Limits for every container: at most the host's hard limits (a container cannot exceed them).
hard_nofile=$(ulimit -Hn) hard_nproc=$(ulimit -Hu)
[[ $hard_nofile == unlimited ]] && hard_nofile=65536
[[ $hard_nproc == unlimited ]] && hard_nproc=65536
NOFILE=$((hard_nofile < 65536 ? hard_nofile : 65536))
NPROC=$((hard_nproc < 8192 ? hard_nproc : 8192))
OPTS=(--runtime runc --ulimit "nofile=$NOFILE:$NOFILE" --ulimit "nproc=$NPROC:$NPROC")

# The image's HEALTHCHECK is run by hand (podman healthcheck run), not by the timer podman puts in
# systemd, which may be absent (podman then logs an error at every start, restart and stop).
export DISABLE_HC_SYSTEMD=true
# Every podman call is bounded: pm SECONDS ARGS...
pm() { local t=$1; shift; timeout --kill-after=10 "$t" podman "$@"; }

timeout 60 podman info >/dev/null 2>&1 || skip "podman info fails here"

TMP=$(mktemp -d)
TAG=voxd-image-check-$$
NAME=$TAG NAME_GPU=$TAG-gpu VOLUME=$TAG
cleanup() {
  local rc=$?
  if ((rc != 0)); then
    for c in "$NAME" "$NAME_GPU"; do
      if pm 30 container exists "$c" 2>/dev/null; then
        echo "-- last log lines of $c:" >&2
        pm 30 logs --tail 30 "$c" >&2 2>&1 || true
      fi
    done
  fi
  pm 60 rm -f -v -t 0 "$NAME" "$NAME_GPU" >/dev/null 2>&1 || true
  pm 60 volume rm -f "$VOLUME" >/dev/null 2>&1 || true
  rm -rf "$TMP"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# The base image: Debian's minbase bookworm from Debian's packages, under the Dockerfile's name,
# configured as Docker's debian:bookworm-slim is (debuerreotype): apt keeps no .deb files or
# caches after an install, and dpkg leaves out documentation, manual pages and translations, in
# this image and in what is installed on top of it (the Dockerfile's apt-get step).
if pm 30 image exists "$BASE"; then
  step "base image $BASE: cached"
else
  command -v mmdebstrap >/dev/null || skip "no $BASE image and no mmdebstrap to make one (apt-get install mmdebstrap)"
  step "base image $BASE: mmdebstrap --variant=minbase bookworm"
  cat >"$TMP/apt-docker-clean" <<'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
EOF
  cat >"$TMP/dpkg-slim" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/lintian/overrides/*
path-exclude /usr/share/locale/*
path-exclude /usr/share/man/*
EOF
  t0=$SECONDS
  # The merged-usr hook merges /usr as Debian 12 requires without the usrmerge package (and the
  # perl it pulls in); the customize hook removes what dpkg unpacked before its excludes applied.
  # shellcheck disable=SC2016 # $1 is the hook's argument, the chroot
  if ! timeout 900 mmdebstrap --variant=minbase --format=tar --aptopt="$TMP/apt-docker-clean" \
    --dpkgopt="$TMP/dpkg-slim" --hook-dir=/usr/share/mmdebstrap/hooks/merged-usr \
    --customize-hook='cd "$1" && find usr/share/doc -mindepth 2 ! -name copyright ! -type d -delete \
      && find usr/share/doc -mindepth 1 -type d -empty -delete \
      && rm -rf usr/share/groff/* usr/share/info/* usr/share/linda/* usr/share/lintian/overrides/* \
        usr/share/locale/* usr/share/man/*' \
    bookworm "$TMP/base.tar" >"$TMP/mmdebstrap.log" 2>&1; then
    tail -20 "$TMP/mmdebstrap.log" >&2
    skip "mmdebstrap could not make the base image"
  fi
  pm 300 import --quiet "$TMP/base.tar" "$BASE" >/dev/null
  rm -f "$TMP/base.tar"
  echo "-- made in $((SECONDS - t0)) s"
fi

step "podman run --runtime runc (can this machine run containers?)"
pm 120 run --rm "${OPTS[@]}" --network none "$BASE" true >"$TMP/trivial.log" 2>&1 \
  || { cat "$TMP/trivial.log" >&2; skip "podman cannot run a container here (podman run --runtime runc failed)"; }

# The build context is the binary alone (the repository's .dockerignore leaves target/ out).
step "podman build (VOXD_BIN_STAGE=prebuilt, binary $BIN)"
mkdir "$TMP/context"
cp "$BIN" "$TMP/context/voxd"
dangling() { pm 30 images -q --no-trunc --filter dangling=true | sort; }
dangling >"$TMP/dangling.before"
t0=$SECONDS
# --format docker: OCI images have no HEALTHCHECK. --pull=never: the base is the local one.
# --layers: the apt-get layer is reused until the Dockerfile or the base changes.
pm 1200 build "${OPTS[@]}" --format docker --pull=never --layers \
  --build-arg VOXD_BIN_STAGE=prebuilt -t "$IMAGE" -f Dockerfile "$TMP/context" >"$TMP/build.log" 2>&1 \
  || { tail -40 "$TMP/build.log" >&2; fail "podman build"; }
echo "-- built in $((SECONDS - t0)) s"
rm -rf "$TMP/context"
# What the build left untagged (the prebuilt stage's image, the previous image when the binary
# changed: 130 MB each for a debug binary) goes, so that runs do not pile them up.
dangling >"$TMP/dangling.after"
comm -13 "$TMP/dangling.before" "$TMP/dangling.after" >"$TMP/dangling.new"
mapfile -t left <"$TMP/dangling.new"
if ((${#left[@]})); then pm 60 rmi "${left[@]}" >/dev/null 2>&1 || true; fi
size=$(pm 30 image inspect --format '{{.Size}}' "$IMAGE")
size_mib=$((size / 1048576))

pm 30 volume create "$VOLUME" >/dev/null

# start NAME [podman run options...]: runs the image detached, port 8080 published on a free
# port of 127.0.0.1 only.
start() {
  local name=$1; shift
  pm 120 run -d --name "$name" "${OPTS[@]}" -p 127.0.0.1::8080 -v "$VOLUME:/data" "$@" "$IMAGE" >/dev/null
}
# url NAME: the published address (looked up again after a restart).
url() {
  local hostport
  hostport=$(pm 30 port "$1" 8080/tcp | head -1)
  [[ $hostport == 127.0.0.1:* ]] || fail "port 8080 of $1 is published on '$hostport', not 127.0.0.1"
  echo "http://$hostport"
}
# wait_healthy NAME: /healthz 200 through the published port, within 60 s.
wait_healthy() {
  local base i
  base=$(url "$1")
  for ((i = 0; i < 120; i++)); do
    if curl -fsS --max-time 2 -o /dev/null "$base/healthz" 2>/dev/null; then
      echo "-- $1: GET $base/healthz 200 after $((i / 2)) s"
      return 0
    fi
    [[ $(pm 30 inspect --format '{{.State.Running}}' "$1") == true ]] || fail "$1 exited before /healthz answered"
    sleep 0.5
  done
  fail "$1: /healthz did not answer 200 within 60 s"
}
# voxelize NAME: one voxelization of tests/data/spot.obj; expects 201 and sets VOL_ID and ENGINE
# from the JSON it answers.
voxelize() {
  local base code
  base=$(url "$1")
  code=$(curl -sS --max-time 90 -o "$TMP/voxelize.json" -w '%{http_code}' --data-binary @tests/data/spot.obj \
    -H 'Content-Type: model/obj' "$base/v1/voxelize?resolution=32&wait=60") || fail "$1: POST /v1/voxelize: curl failed"
  [[ $code == 201 ]] || { cat "$TMP/voxelize.json" >&2; fail "$1: POST /v1/voxelize answered $code, not 201"; }
  VOL_ID=$(sed -n 's/^{"id":"\([0-9a-zA-Z_-]*\)".*/\1/p' "$TMP/voxelize.json")
  ENGINE=$(sed -n 's/.*"engine":"\([^"]*\)".*/\1/p' "$TMP/voxelize.json")
  [[ -n $VOL_ID ]] || { cat "$TMP/voxelize.json" >&2; fail "$1: no id in the voxelization's JSON"; }
  echo "-- $1: POST /v1/voxelize 201, id $VOL_ID, engine $ENGINE"
}
# proc_field NAME PID FIELD: a field of /proc/PID/status inside the container.
proc_field() { pm 30 exec "$1" sh -c "sed -n 's/^$3:[[:space:]]*//p' /proc/$2/status"; }

step "run $IMAGE as $NAME (volume $VOLUME on /data)"
start "$NAME"
wait_healthy "$NAME"
voxelize "$NAME"
id=$VOL_ID

# PID 1 is tini, running as 10001; voxd is its child, as 10001 too.
pid1_name=$(proc_field "$NAME" 1 Name)
pid1_uid=$(proc_field "$NAME" 1 Uid)
[[ $pid1_name == tini ]] || fail "PID 1 is '$pid1_name', not tini"
# shellcheck disable=SC2016 # expanded by the container's sh
voxd_pid=$(pm 30 exec "$NAME" sh -c 'for s in /proc/[0-9]*/status; do
  if grep -qx "Name:[[:space:]]*voxd" "$s" && grep -qx "PPid:[[:space:]]*1" "$s"; then p=${s#/proc/}; echo "${p%/status}"; fi; done')
[[ $voxd_pid =~ ^[0-9]+$ ]] || fail "no single voxd process whose parent is PID 1 (found '$voxd_pid')"
voxd_uid=$(proc_field "$NAME" "$voxd_pid" Uid)
voxd_gid=$(proc_field "$NAME" "$voxd_pid" Gid)
read -r -a u1 <<<"$pid1_uid"
read -r -a uv <<<"$voxd_uid"
read -r -a gv <<<"$voxd_gid"
[[ ${u1[*]} == "10001 10001 10001 10001" ]] || fail "tini runs as uids '$pid1_uid', not 10001"
[[ ${uv[*]} == "10001 10001 10001 10001" && ${gv[*]} == "10001 10001 10001 10001" ]] \
  || fail "voxd runs as uids '$voxd_uid' gids '$voxd_gid', not 10001"
echo "-- PID 1 tini (uid 10001), voxd PID $voxd_pid child of tini (uid/gid 10001)"
pm 30 top "$NAME" user pid ppid args | sed 's/^/   /' || true

# The image's HEALTHCHECK, as podman keeps it from the docker-format image.
hc=$(pm 30 inspect --format '{{.Config.Healthcheck.Test}}' "$NAME" 2>/dev/null || true)
[[ $hc == *healthz* ]] || fail "the container has no HEALTHCHECK from the image (got '$hc')"
pm 60 healthcheck run "$NAME" || fail "podman healthcheck run $NAME exited $?"
echo "-- podman healthcheck run: healthy ($hc)"

step "podman restart $NAME"
pm $((GRACE + 60)) restart -t "$GRACE" "$NAME" >/dev/null
wait_healthy "$NAME"
code=$(curl -sS --max-time 10 -o /dev/null -w '%{http_code}' "$(url "$NAME")/v1/volumes/$id")
[[ $code == 200 ]] || fail "GET /v1/volumes/$id after the restart answered $code, not 200"
echo "-- GET /v1/volumes/$id after the restart: 200"

step "podman stop -t $GRACE $NAME"
t0=$(date +%s%N)
pm $((GRACE + 60)) stop -t "$GRACE" "$NAME" >/dev/null || fail "podman stop exited $?"
stop_ms=$((($(date +%s%N) - t0) / 1000000))
stop_s=$(printf '%d.%02d' $((stop_ms / 1000)) $((stop_ms % 1000 / 10)))
((stop_ms < GRACE * 1000)) || fail "podman stop took ${stop_s} s: voxd did not stop within the ${GRACE} s grace period (SIGKILL)"
exit_code=$(pm 30 inspect --format '{{.State.ExitCode}}' "$NAME")
[[ $exit_code == 0 ]] || fail "the container exited $exit_code after SIGTERM, not 0"
echo "-- stopped in ${stop_s} s, exit code 0"

step "run $IMAGE as $NAME_GPU with VOXD_ENGINE=gpu (lavapipe inside the image)"
start "$NAME_GPU" -e VOXD_ENGINE=gpu
wait_healthy "$NAME_GPU"
voxelize "$NAME_GPU"
[[ $ENGINE == gpu* ]] || fail "VOXD_ENGINE=gpu voxelized with engine '$ENGINE'"
pm $((GRACE + 60)) stop -t "$GRACE" "$NAME_GPU" >/dev/null

echo "image-check: OK, image size $size_mib MiB, stop took $stop_s s ($((SECONDS - START)) s in all)"
