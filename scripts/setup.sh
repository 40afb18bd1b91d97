#!/usr/bin/env bash
# Installs the Debian packages prtbake needs (as root, or via sudo) and builds it into build/.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/packages.sh
# shellcheck disable=SC2086  # the list is split into packages on purpose
install_missing $PRTBAKE_PKGS
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release ${PRTBAKE_CMAKE_ARGS:-}
cmake --build build -j"$(nproc)"
