# Sourced by setup.sh and bench/study/run.sh: the Debian packages prtbake builds and tests
# with, and install_missing, which installs those of its arguments that are not installed
# (as root, or via sudo).
# PRTBAKE_BUILD_PKGS: the library and the CLI; PRTBAKE_TEST_PKGS adds the tests' needs
# (Catch2, Slurm and Munge for the throw-away cluster of the Slurm test, and Chromium, which
# runs the glossy GLSL of docs/glsl/ headless in test_glossy_glsl; Debian's NumPy and pybind11
# for the Python module, pytest and mypy for its tests; strace, whose fault injection fails single
# writes and fsyncs in tests/queue/full_disk.py).
PRTBAKE_BUILD_PKGS="build-essential cmake pocl-opencl-icd ocl-icd-opencl-dev opencl-clhpp-headers clinfo \
libopenexr-dev libtinygltf-dev libtinyobjloader-dev libglm-dev libstb-dev nlohmann-json3-dev"
PRTBAKE_TEST_PKGS="$PRTBAKE_BUILD_PKGS catch2 slurm-wlm munge chromium python3-dev python3-numpy python3-pybind11 pybind11-dev \
python3-pytest mypy strace"
# The KTX2 read-back tests run ktx-parse (tests/js) on Node: nodejs, and npm where the nodejs
# package does not bring it (NodeSource's does; Debian's does not).
PRTBAKE_PKGS=$PRTBAKE_TEST_PKGS

install_missing() {
  local missing="" p sudo=""
  for p in "$@"; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
  [ -n "$missing" ] || return 0
  [ "$(id -u)" = 0 ] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends $missing
}

# Node and npm for the KTX2 read-back tests, then the pinned modules of tests/js (npm ci). A
# machine without the npm registry keeps going: those tests then skip and say why.
install_node_tools() {
  install_missing nodejs
  command -v npm >/dev/null 2>&1 || install_missing npm
  if [ ! -f tests/js/node_modules/.package-lock.json ] || [ tests/js/package-lock.json -nt tests/js/node_modules/.package-lock.json ]; then
    (cd tests/js && npm ci --no-audit --no-fund --loglevel=error) ||
      echo "setup: npm ci in tests/js failed (no registry?): the KTX2 read-back tests will be skipped" >&2
  fi
}
