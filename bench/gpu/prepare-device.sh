#!/usr/bin/env bash
# Prepares a run of bench/gpu/device.sh on a lent GPU machine (the device tool; issue 14 item
# 6): builds voxd and examples/gpu_small_jobs here (release), strips them into .device/ with
# the meshes the script times (from ../shared/meshes, which does not travel), and downloads the
# Vulkan loader's Debian packages into .gl/ (the device machine may lack them). Both folders are
# added to .git/info/exclude. Then, in one device call:
#
#   run(command: "bash bench/gpu/device.sh", carry: [".device", ".gl"], timeout_s: 540)
#
# The files come back under $OUT: one markdown report and the raw outputs.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
meshes=${MESHES:-$root/../shared/meshes}
cargo build --release --locked --bin voxd --example gpu_small_jobs
rm -rf .device && mkdir -p .device/meshes
strip -o .device/voxd target/release/voxd
strip -o .device/gpu_small_jobs target/release/examples/gpu_small_jobs
# The integration tests' binary (release), for its GPU == CPU tests (tests/gpu.rs) on the device.
tests=$(cargo test --release --locked --test integration --no-run --message-format=json 2>/dev/null \
  | python3 -c 'import json, sys
for l in sys.stdin:
    m = json.loads(l) if l.startswith("{") else {}
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["name"] == "integration":
        print(m["executable"])' | tail -1)
strip -o .device/integration "$tests"
cp tests/data/spot.obj bench/load/cube.obj .device/meshes/
# Every shared mesh (29 MB): the benchmarks' and the GPU tests' (tests/gpu.rs reads the folder
# through VOXD_SHARED_MESHES there).
if [[ -f $meshes/README.md ]]; then cp "$meshes"/* .device/meshes/; else echo "NOTICE: no $meshes; device.sh skips the real meshes" >&2; fi
# The tests find tests/data under the checkout's path here (compiled in): device.sh links it.
echo "$root" >.device/manifest_dir
for d in /.device/ /.gl/; do grep -qxF "$d" .git/info/exclude 2>/dev/null || echo "$d" >>.git/info/exclude; done
if [[ ! -d .gl ]] || ! compgen -G ".gl/*.deb" >/dev/null; then
  mkdir -p .gl /tmp/amd64/partial
  o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
  # shellcheck disable=SC2086
  apt-get $o update -qq >/dev/null
  # shellcheck disable=SC2086
  (cd .gl && apt-get $o download libvulkan1 >/dev/null)
fi
# The device call carries at most 64 MiB: everything but manifest_dir travels as one xz archive
# (≈ 29 MB of ≈ 80), which device.sh unpacks.
(cd .device && tar -cf - voxd gpu_small_jobs integration meshes | xz -T0 -4 >pack.tar.xz && rm -rf voxd gpu_small_jobs integration meshes)
du -sh .device .gl
