#!/usr/bin/env bash
# Installs the Debian 12 packages rgbd-toolkit needs, then configures and builds it into
# build/ (Release, Ninja). Safe to run again: apt-get and ninja skip what is done.
# Usage: bash scripts/setup.sh   (as root, or as a user with sudo)
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(build-essential cmake ninja-build pkg-config
  libcgal-dev libgmp-dev libmpfr-dev libeigen3-dev libopencv-dev libopencv-contrib-dev libtbb-dev
  libboost-dev libboost-program-options-dev libnanoflann-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libzmq3-dev cppzmq-dev zlib1g-dev libpng-dev libjpeg-dev libopenni2-dev iproute2 libdraco-dev libtinygltf-dev
  libjs-three curl libcgal-demo python3-open3d python3-numpy pybind11-dev chromium snakemake assimp-utils
  slurm-wlm munge)

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# ccache, when installed, makes a second clone or a rebuild after a branch switch cheap.
LAUNCHER=()
if command -v ccache >/dev/null; then
  LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "${LAUNCHER[@]}" >/dev/null
ninja -C build -j"$(nproc)"
