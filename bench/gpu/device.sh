#!/usr/bin/env bash
# Runs ON a lent GPU machine (prepared by bench/gpu/prepare-device.sh; see there for the call):
# the engines side by side on one machine, bounded to ~8 minutes, into $OUT/report.md:
#   1. `voxd bench` (CPU and GPU per method and resolution, with the GPU's upload / dispatch /
#      readback and whether the bits agree) on igea-subdiv4 and stanford-bunny;
#   2. the whole `voxd voxelize` command, CPU engine against GPU engine, interleaved, 3 runs each;
#   0. the GPU tests (tests/gpu.rs: every kernel against the CPU engine, bit for bit) on the
#      device's adapter, from the integration tests' release binary;
#   2b. `distance` against `surface` on each engine, once the CLI has `--method distance`;
#   3. small jobs from 1, 4 and 16 threads on one GPU engine (examples/gpu_small_jobs, every
#      volume checked against the CPU engine's).
# Every step has its own timeout; a step that fails is reported and the rest go on.
set -uo pipefail
cd "$(dirname "$0")/../.."
out=${OUT:-/tmp/voxd-device}
mkdir -p "$out"
report=$out/report.md
for f in .gl/*.deb; do [[ -f $f ]] && dpkg -x "$f" /; done
ldconfig 2>/dev/null
if [[ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]] && ! compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null; then
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi
# In a headless container NVIDIA's GLX ICD (the nvidia_icd.json the toolkit mounts) fails:
# "Could not get 'vkCreateInstance' via 'vk_icdGetInstanceProcAddr' for ICD libGLX_nvidia.so.0"
# and no adapter is found; the same driver's EGL library works without a display (2026-12-04,
# H200, driver 580.159.04). So the ICD named is the EGL one where it exists.
if ldconfig -p 2>/dev/null | grep -q 'libEGL_nvidia\.so\.0' || [[ -e /usr/local/nvidia/lib64/libEGL_nvidia.so.0 ]]; then
  printf '{"file_format_version":"1.0.1","ICD":{"library_path":"libEGL_nvidia.so.0","api_version":"1.3.0"}}\n' >/tmp/voxd_nvidia_egl_icd.json
  export VK_DRIVER_FILES=/tmp/voxd_nvidia_egl_icd.json VK_ICD_FILENAMES=/tmp/voxd_nvidia_egl_icd.json
fi
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)} VOXD_ADAPTER=${VOXD_ADAPTER:-NVIDIA}
export d=.device out
if [[ -f $d/pack.tar.xz ]]; then
  tar -xJf $d/pack.tar.xz -C $d 2>/dev/null || python3 -c 'import sys, tarfile; tarfile.open(sys.argv[1]).extractall(sys.argv[2])' $d/pack.tar.xz $d
fi
step() { # TITLE SECONDS COMMAND...
  local title=$1 secs=$2; shift 2
  echo "## $title" >>"$report"
  echo >>"$report"
  echo "\`$*\`" >>"$report"
  echo >>"$report"
  local t0=$SECONDS
  # A shell function (whole) runs in a bash of its own, so that timeout can stop it.
  timeout "$secs" bash -c "$(declare -f "$1" 2>/dev/null)
\"\$@\"" _ "$@" >>"$report" 2>>"$out/stderr.log" \
    || echo "(step failed or timed out: rc $?)" >>"$report"
  echo -e "\n($((SECONDS - t0)) s)\n" >>"$report"
}
{
  echo "# voxd on $(nvidia-smi -L 2>/dev/null | head -1 || echo 'an unknown GPU')"
  echo
  echo "$(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), $(free -g | awk '/Mem/ {print $2}') GiB; voxd $(sha256sum $d/voxd | cut -c1-12); $(date -u)"
  echo
} >"$report"
gputests() { # the GPU tests on this adapter (VOXD_REQUIRE_GPU: no adapter is a failure)
  local m; m=$(cat $d/manifest_dir 2>/dev/null)
  [[ -n $m && ! -e $m ]] && mkdir -p "$(dirname "$m")" && ln -s "$PWD" "$m"
  echo '```'
  VOXD_SHARED_MESHES=$PWD/$d/meshes VOXD_REQUIRE_GPU=1 $d/integration gpu:: --test-threads 4 2>&1 | grep -E '^(test |GPU tests on|test result|failures|---- )' | tail -80
  echo '```'
}
[[ -x $d/integration ]] && step "GPU tests (tests/gpu.rs) on the device" 150 gputests
[[ -f $d/meshes/igea-subdiv4.obj.gz && -z ${SKIP_BENCH:-} ]] && step "voxd bench: igea-subdiv4" 150 $d/voxd bench $d/meshes/igea-subdiv4.obj.gz --resolutions 256,512,1024 --methods solid,surface --runs 3
[[ -f $d/meshes/stanford-bunny.obj && -z ${SKIP_BENCH:-} ]] && step "voxd bench: stanford-bunny" 90 $d/voxd bench $d/meshes/stanford-bunny.obj --resolutions 128,256,512 --runs 3
whole() { # MESH RES: the whole command, cpu and gpu interleaved, 3 runs each (wall seconds)
  echo "| engine | run 1 | run 2 | run 3 |"
  echo "|---|---|---|---|"
  declare -A t
  for r in 1 2 3; do
    for e in cpu gpu; do
      local s=$EPOCHREALTIME
      $d/voxd voxelize "$1" --resolution "$2" --cubic --engine "$e" -o /tmp/whole-$e.vxl >/dev/null 2>>"$out/stderr.log" || { echo "| $e | failed | | |"; return 1; }
      t[$e,$r]=$(awk -v a="$s" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.3f", b - a }')
    done
  done
  for e in cpu gpu; do echo "| $e | ${t[$e,1]} s | ${t[$e,2]} s | ${t[$e,3]} s |"; done
  cmp -s /tmp/whole-cpu.vxl /tmp/whole-gpu.vxl && echo -e "\nvolumes identical" || echo -e "\nVOLUMES DIFFER"
}
if [[ -f $d/meshes/igea-subdiv4.obj.gz ]]; then
  for n in 256 512; do step "whole voxd voxelize, igea-subdiv4 at $n³" 120 whole $d/meshes/igea-subdiv4.obj.gz $n; done
fi
distance_vs_surface() { # MESH RES: `distance` (default thickness) against `surface`, each engine (wall seconds)
  echo "| engine | surface | distance |"
  echo "|---|---|---|"
  for e in cpu gpu; do
    local row="| $e |"
    for m in surface distance; do
      local s=$EPOCHREALTIME
      if $d/voxd voxelize "$1" --resolution "$2" --cubic --engine "$e" --method "$m" -o /tmp/dvs-$e-$m.vxl >/dev/null 2>>"$out/stderr.log"; then
        row+=" $(awk -v a="$s" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.3f", b - a }') s |"
      else
        row+=" failed |"
      fi
    done
    echo "$row"
  done
  cmp -s /tmp/dvs-cpu-distance.vxl /tmp/dvs-gpu-distance.vxl && echo -e "\ndistance volumes identical" || echo -e "\nDISTANCE VOLUMES DIFFER"
}
# Once the CLI knows `--method distance`.
if [[ -f $d/meshes/igea-subdiv4.obj.gz ]] && $d/voxd voxelize --help 2>/dev/null | grep -q distance; then
  step "distance against surface, igea-subdiv4 at 512³" 120 distance_vs_surface $d/meshes/igea-subdiv4.obj.gz 512
fi
for c in "cube.obj 64 2000" "spot.obj 64 2000" "spot.obj 128 500"; do
  read -r m n jobs <<<"$c"
  for th in 1 4 16; do step "small jobs: $m at $n³, $jobs jobs, $th threads" 60 $d/gpu_small_jobs $d/meshes/$m "$n" "$jobs" "$th"; done
done
echo "report: $report" >&2
