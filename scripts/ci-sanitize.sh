#!/usr/bin/env bash
# Builds the loader, job and corpus tests (and the CLI they run) with
# AddressSanitizer + UndefinedBehaviorSanitizer in build-sanitize/ and runs them.
#
# Scope: the environment loaders, job files, the runner and its confinement, the bad-input
# corpus and every fuzz target over its seeds and regression inputs (test_env_load,
# test_env_files, test_jobs, test_confine, test_corpus, test_fuzz_replay). These run the
# CLI, which is built with the sanitizers too, so every corpus case is decoded under ASan/UBSan.
# OpenCL under ASan: these tests create OpenCL contexts (PoCL), in the test
# processes and in the CLI. With Debian's PoCL 3.1 and ocl-icd, LeakSanitizer
# reports no leaks and ASan nothing inside the ICD, so no suppressions are used
# and the OpenCL tests stay in the sanitized run. Should another PoCL report
# leaks it keeps until exit, suppress those (and only those) with
# LSAN_OPTIONS=suppressions=FILE holding "leak:libpocl" and "leak:libOpenCL".
#
# Usage: scripts/ci-sanitize.sh [Catch2 args, e.g. a test-case filter]. Env: JOBS (default nproc).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${PRTBAKE_SANITIZE_BUILD_DIR:-$root/build-sanitize}
jobs=${JOBS:-$(nproc)}
start=$(date +%s)

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPRTBAKE_SANITIZE=ON -DPRTBAKE_BUILD_BENCH=OFF -DPRTBAKE_PYTHON=OFF \
  ${PRTBAKE_CMAKE_ARGS:-} >/dev/null
cmake --build "$build" -j"$jobs" --target prtbake_cli test_env_load test_env_files test_jobs test_confine test_corpus test_fuzz_replay

# use_sigaltstack=0: LLVM (PoCL's compiler) gives a thread where it runs an alternate signal stack
# from malloc, which ASan's thread teardown then unmaps as its own ("CHECK failed: unable to
# unmap", rc 134): every command that starts the device on a second thread (transport, probes,
# lightmap) ended so under ASan, success or error alike.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1:use_sigaltstack=0"
export LSAN_OPTIONS="suppressions=$root/tests/sanitizer/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export POCL_CACHE_DIR="$build/pocl-cache"
# The test executables are run directly (ctest -R matches test-case names,
# not executables); each runs all of its cases in one process.
failed=""
for t in test_env_load test_env_files test_jobs test_confine test_corpus test_fuzz_replay; do
  echo "== $t (ASan+UBSan)"
  "$build/tests/$t" "$@" || failed="$failed $t"
done
if [ -n "$failed" ]; then
  echo "ci-sanitize: FAILED:$failed ($(( $(date +%s) - start )) s)" >&2
  exit 1
fi
echo "ci-sanitize: passed in $(( $(date +%s) - start )) s"
