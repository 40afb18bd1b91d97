#!/usr/bin/env bash
# First runs with an empty program cache, as every fresh node of a batch job pays them:
# `prtbake lut` (defaults) and `prtbake transport` on mary.obj (defaults), each in a new,
# empty POCL_CACHE_DIR (PoCL's cache is the only program cache; prtbake keeps none), then
# the same commands warm. RUNS rounds (default 5), the cold runs of both commands
# alternating, so that each round shares the machine's conditions. Whole commands: wall
# time and peak memory from /usr/bin/time. Writes bench/results/cold.md.
#   bash bench/bench_cold.sh [BUILD]     (BUILD: default build/)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}
OUT=$ROOT/bench/results/cold.md
MARY=${PRTBAKE_DATA_DIR:-$ROOT/../shared/data}/meshes/obj/mary.obj
[ -f "$MARY" ] || { echo "bench_cold.sh: $MARY is absent (../shared/data): nothing measured" >&2; exit 2; }
PRTBAKE=$BUILD/prtbake
RUNS=${RUNS:-5}
[ "$RUNS" -ge 3 ] || { echo "bench_cold.sh: RUNS must be at least 3" >&2; exit 2; }
work=$(mktemp -d /tmp/prtbake-bench-cold.XXXXXX)
trap 'rm -rf "$work"' EXIT
timed() {  # label, cache dir, command...: prints "label wall_s peak_MiB"
  local label=$1 cache=$2; shift 2
  POCL_CACHE_DIR=$cache /usr/bin/time -f "$label %e %M" -o "$work/time.txt" "$@" > "$work/out.txt" 2>&1 ||
    { cat "$work/out.txt" >&2; exit 1; }
  awk '{printf "%s %.2f %.0f\n", $1, $2, $3 / 1024}' "$work/time.txt"
}
lut=("$PRTBAKE" lut -o "$work/lut.exr" --quiet)
mary=("$PRTBAKE" transport "$MARY" -o "$work/mary.npy" --quiet)
cold=() warm=()
for run in $(seq "$RUNS"); do
  rm -rf "$work/cache" && mkdir "$work/cache"
  cold+=("$(timed lut "$work/cache" "${lut[@]}")")
  rm -rf "$work/cache" && mkdir "$work/cache"
  cold+=("$(timed mary "$work/cache" "${mary[@]}")")
done
POCL_CACHE_DIR=$work/cache "${lut[@]}" && POCL_CACHE_DIR=$work/cache "${mary[@]}"  # both programs cached
for run in $(seq "$RUNS"); do
  warm+=("$(timed lut "$work/cache" "${lut[@]}")")
  warm+=("$(timed mary "$work/cache" "${mary[@]}")")
done
summary() {  # kind, "label wall peak" lines: one table row per command
  awk -v kind="$1" '
    function median(a, n,   i, j, t) { for (i = 1; i <= n; ++i) for (j = i + 1; j <= n; ++j) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t } return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2 }
    { n[$1]++; w[$1, n[$1]] = $2; all[$1] = all[$1] (n[$1] > 1 ? ", " : "") $2; if ($3 > peak[$1]) peak[$1] = $3 }
    END { for (c in n) { m = n[c]; for (i = 1; i <= m; ++i) v[i] = w[c, i];
      printf "| %s | %s | %.2f | %s | %d |\n", c, kind, median(v, m), all[c], peak[c] } }' | sort
}
{
  echo "# Cold start: first runs with an empty program cache"
  echo
  echo "bench/bench_cold.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)); PoCL $(dpkg-query -W -f='${Version}' pocl-opencl-icd 2>/dev/null || echo '?'), CPU device; $RUNS rounds. Cold: a new, empty POCL_CACHE_DIR for every run (the file cache warm); warm: the same commands with the programs cached."
  echo
  echo "| command | cache | median wall [s] | runs [s] | peak [MiB] |"
  echo "|---|---|---|---|---|"
  printf '%s\n' "${cold[@]}" | summary cold
  printf '%s\n' "${warm[@]}" | summary warm
  echo
  echo "lut: \`prtbake lut\` with its defaults; mary: \`prtbake transport mary.obj\` with its defaults (shadowed, order 3)."
} > "$OUT"
cat "$OUT"
