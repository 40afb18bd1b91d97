#!/usr/bin/env bash
# Installs the Debian packages prtbake needs (as root, or via sudo) and builds it into build/.
#   setup.sh          everything: library, CLI, tests and benchmarks (what scripts/test.sh runs)
#   setup.sh --cli    the library and the prtbake command only, with the packages they need
#                     (what scripts/demo.sh runs: no Catch2, Slurm or Munge, no test programs)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/packages.sh
if [ "${1:-}" = --cli ]; then
  # shellcheck disable=SC2086  # the list is split into packages on purpose
  install_missing $PRTBAKE_BUILD_PKGS
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DPRTBAKE_BUILD_TESTS=OFF -DPRTBAKE_BUILD_BENCH=OFF \
    ${PRTBAKE_CMAKE_ARGS:-}
  cmake --build build -j"$(nproc)" --target prtbake_cli
else
  # shellcheck disable=SC2086
  install_missing $PRTBAKE_TEST_PKGS
  install_node_tools
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DPRTBAKE_BUILD_TESTS=ON -DPRTBAKE_BUILD_BENCH=ON \
    ${PRTBAKE_CMAKE_ARGS:-}
  cmake --build build -j"$(nproc)"
fi
