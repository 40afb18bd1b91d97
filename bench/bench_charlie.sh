#!/usr/bin/env bash
# Charlie (sheen) prefiltering, the narrow ring near the horizon: accuracy of the cut against the
# double brute force on the four maps, and whole-command times and peak memory at 64² and 256²
# (filament schedule, whose r = 0 level is the thinnest ring); writes bench/results/charlie.md.
#   bash bench/bench_charlie.sh [BUILD] [BASELINE_CLI]
# BASELINE_CLI: another build's prtbake (an earlier commit), timed alternately in the same run.
# Needs ../shared/data/envmaps/hdr (the four 1k HDR maps with suns).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}
BASE=${2:-}
BENCH=$BUILD/bench/bench_prefilter
OUT=$ROOT/bench/results/charlie.md
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$BUILD/pocl-cache}
HDR=$ROOT/../shared/data/envmaps/hdr
[ -d "$HDR" ] || { echo "bench_charlie.sh: no $HDR (the shared HDR maps)" >&2; exit 1; }
MAPS=("$HDR"/*.hdr "$HDR"/*.exr)
SUN=$HDR/venice_sunset_1k.hdr
timed() {  # label, command...: wall, CPU and peak of one run
  local label=$1 tf
  shift
  tf=$(mktemp)
  /usr/bin/time -o "$tf" -f '%e %U %S %M' "$@" >/dev/null 2>&1
  read -r wall user sys peak <"$tf"
  rm -f "$tf"
  echo "| $label | $wall | $(awk -v a="$user" -v b="$sys" 'BEGIN { print a + b }') | $((peak / 1024)) |"
}
tmp=$(mktemp)
{
  echo "# Charlie (sheen) prefiltering"
  echo
  echo "bench/bench_charlie.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), PoCL CPU device; load average at the start $(cut -d' ' -f1 /proc/loadavg)."
  echo
  echo "## Accuracy against the double brute force"
  echo
  echo "filament schedule, 256² base, --lobe charlie; relative error (max over channels) at 400 uniformly drawn texels per level plus the 64 nearest each map's brightest texel."
  echo
  "$BENCH" accuracy "${MAPS[@]}" --size 256 --schedule filament --lobe charlie --method cut
  echo
  echo "## Whole commands (warm program caches), three alternating runs each"
  echo
  echo "| command | wall [s] | CPU [s] | peak [MiB] |"
  echo "|---|---|---|---|"
  o=$(mktemp -d)
  "$BUILD/prtbake" prefilter "$SUN" -o "$o/w.ktx2" --size 16 --lobe charlie -q  # warm the program caches
  [ -z "$BASE" ] || "$BASE" prefilter "$SUN" -o "$o/w.ktx2" --size 16 --lobe charlie -q
  for size in 64 256; do
    for run in 1 2 3; do
      timed "prtbake prefilter $(basename "$SUN") --lobe charlie --schedule filament --size $size (#$run)" \
        "$BUILD/prtbake" prefilter "$SUN" -o "$o/c.ktx2" --size $size --schedule filament --lobe charlie -q
      [ -z "$BASE" ] || timed "baseline ($BASE), --size $size (#$run)" \
        "$BASE" prefilter "$SUN" -o "$o/b.ktx2" --size $size --schedule filament --lobe charlie -q
    done
  done
  rm -rf "$o"
} | tee "$tmp"
mv "$tmp" "$OUT"
echo "wrote $OUT" >&2
