#!/usr/bin/env bash
# Makes sure a Vulkan driver exists for the GPU engine: on a machine with none, installs Mesa's
# lavapipe (Debian: mesa-vulkan-drivers). Prints what it did; exits 0 even when it cannot install
# (voxd then runs on its CPU engine, and the GPU tests skip unless VOXD_REQUIRE_GPU=1).
set -uo pipefail
has_icd() { compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null || compgen -G "/etc/vulkan/icd.d/*.json" >/dev/null; }
if has_icd && ldconfig -p 2>/dev/null | grep -q libvulkan.so.1; then
  exit 0
fi
sudo=""
[[ $(id -u) == 0 ]] || sudo=$(command -v sudo || true)
if [[ $(id -u) != 0 && -z $sudo ]] || ! command -v apt-get >/dev/null; then
  echo "NOTICE: no Vulkan driver and no way to install one here; voxd will use its CPU engine" >&2
  exit 0
fi
echo "installing mesa-vulkan-drivers (lavapipe) for the GPU engine" >&2
($sudo apt-get update -qq || true) >/dev/null 2>&1
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null || echo "NOTICE: installing mesa-vulkan-drivers failed" >&2
exit 0
