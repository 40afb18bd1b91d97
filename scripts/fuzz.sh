#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/) with clang, ASan and UBSan in build-fuzz/
# and runs each for a fixed time on its corpus. Exit 1 when any target finds a crash,
# a leak, undefined behaviour, a timeout or a contract violation; the input is kept in
# build-fuzz/findings/<target>/ and the log in build-fuzz/logs/<target>.log.
#
# usage: scripts/fuzz.sh [--seconds S] [--build-only] [TARGET ...]
#   --seconds S   run time per target (default 60); TARGETs default to all of them
# The working corpus of each target (build-fuzz/corpus/<target>/) keeps what earlier
# runs found and starts from the committed seeds (tests/fuzz/corpus/<target>/).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
seconds=60
build_only=0
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --build-only) build_only=1; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done

. scripts/packages.sh
# shellcheck disable=SC2086
install_missing $PRTBAKE_BUILD_PKGS clang libclang-rt-14-dev
build=${PRTBAKE_FUZZ_BUILD_DIR:-$root/build-fuzz}
CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPRTBAKE_FUZZ=ON -DPRTBAKE_PYTHON=OFF \
  -DPRTBAKE_BUILD_BENCH=OFF -Wno-dev >/dev/null
if [ ${#targets[@]} -eq 0 ]; then
  for f in tests/fuzz/fuzz_*.cpp; do t=$(basename "$f" .cpp); targets+=("${t#fuzz_}"); done
fi
cmake --build "$build" -j"$(nproc)" --target "${targets[@]/#/fuzz_}"
[ "$build_only" = 1 ] && exit 0

dict_of() {
  case "$1" in
    env_image|env_faces|lut_exr) echo tests/fuzz/image.dict ;;
    gltf|lightmap) echo tests/fuzz/gltf.dict ;;
    obj) echo tests/fuzz/obj.dict ;;
    jobfile|sh_json) echo tests/fuzz/json.dict ;;
    npy|glossy) echo tests/fuzz/npy.dict ;;
  esac
}

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
mkdir -p "$build/logs"
failed=()
printf '%-10s %8s %10s %8s %8s %6s  %s\n' target seconds executions exec/s cov corpus result
for t in "${targets[@]}"; do
  exe="$build/tests/fuzz/fuzz_$t"
  [ -x "$exe" ] || { echo "fuzz: no target '$t'" >&2; exit 2; }
  mkdir -p "$build/corpus/$t" "$build/findings/$t"
  log="$build/logs/$t.log"
  dict=$(dict_of "$t")
  status=0
  # -timeout: an input that takes longer is a hang. -malloc_limit_mb: one block of 512 MiB
  # or more is a finding: the targets cap what a file may decode to
  # (tests/fuzz/support.cpp: 128 MiB) and refuse a file too short for its header's claim, so only a
  # block that neither check accounted for gets there. -rss_limit_mb: the whole process.
  "$exe" -max_total_time="$seconds" -timeout=20 -malloc_limit_mb=512 -rss_limit_mb=2048 -print_final_stats=1 \
    ${dict:+-dict="$dict"} -artifact_prefix="$build/findings/$t/" \
    "$build/corpus/$t" "tests/fuzz/corpus/$t" >"$log" 2>&1 || status=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
  corpus=$(find "$build/corpus/$t" -type f | wc -l)
  result=ok
  if [ "$status" -ne 0 ]; then
    result="FINDING (exit $status, see $log)"
    failed+=("$t")
  fi
  printf '%-10s %8s %10s %8s %8s %6s  %s\n' "$t" "$seconds" "${execs:-?}" "${rate:-?}" "${cov:-?}" "$corpus" "$result"
  if [ "$status" -ne 0 ]; then
    grep -a -m1 -B2 -A25 -E 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error|fuzz contract violated|deadly signal' "$log" |
      cut -c1-200 | head -30 >&2 || tail -30 "$log" >&2
    ls "$build/findings/$t" >&2
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in: ${failed[*]}" >&2
  exit 1
fi
