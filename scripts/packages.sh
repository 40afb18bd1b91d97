# Sourced by setup.sh and bench/study/run.sh: the Debian packages prtbake builds and tests
# with, and install_missing, which installs those of its arguments that are not installed
# (as root, or via sudo).
PRTBAKE_PKGS="build-essential cmake pocl-opencl-icd ocl-icd-opencl-dev opencl-clhpp-headers clinfo \
libopenexr-dev libtinygltf-dev libtinyobjloader-dev libglm-dev catch2 libstb-dev nlohmann-json3-dev \
slurm-wlm munge"

install_missing() {
  local missing="" p sudo=""
  for p in "$@"; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
  [ -n "$missing" ] || return 0
  [ "$(id -u)" = 0 ] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends $missing
}
