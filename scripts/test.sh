#!/usr/bin/env bash
# Builds (via setup.sh) and runs the whole test suite with ctest. A test that cannot run
# here (no external data in ../shared/data, not root for the Slurm test, ...) is counted
# as skipped; the reasons are listed after ctest's summary. With PRTBAKE_FORBID_SKIPS=1
# (CI) a skip fails its test instead. Then every kernel variant the host can build, and
# every one the tests built, is compiled for NVIDIA's OpenCL target (nvptx_check.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
skips=build/Testing/skipped.log
mkdir -p build/Testing
rm -f "$skips"
export PRTBAKE_BUILD_LOG=$PWD/build/Testing/programs.log
rm -f "$PRTBAKE_BUILD_LOG"
status=0
ctest --test-dir build --output-on-failure -j"$(nproc)" || status=$?
if [ -s "$skips" ]; then
  echo
  echo "Why the skipped tests did not run (a skipped test checked nothing):"
  sort -u "$skips" | sed 's/^/  /'
fi
build/tests/kernel_variants >build/Testing/kernel_variants.txt
bash scripts/nvptx_check.sh build/Testing/kernel_variants.txt "$PRTBAKE_BUILD_LOG" || status=1
exit $status
