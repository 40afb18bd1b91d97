#!/usr/bin/env bash
# Installs the Debian packages prtbake needs (as root, or via sudo) and builds it into build/.
set -euo pipefail
cd "$(dirname "$0")/.."
PKGS="build-essential cmake pocl-opencl-icd ocl-icd-opencl-dev opencl-clhpp-headers clinfo \
libopenexr-dev libtinygltf-dev libtinyobjloader-dev libglm-dev catch2 libstb-dev nlohmann-json3-dev \
slurm-wlm munge"
missing=""
for p in $PKGS; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release ${PRTBAKE_CMAKE_ARGS:-}
cmake --build build -j"$(nproc)"
