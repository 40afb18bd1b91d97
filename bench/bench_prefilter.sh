#!/usr/bin/env bash
# Prefiltered specular: accuracy against the double brute force, the anchors' sampled
# estimator at equal error, and whole-command times and peak memory, in one run; writes
# bench/results/prefilter.md.
#   bash bench/bench_prefilter.sh [BUILD]      (BUILD: default build/, with bench_prefilter built)
# Needs ../shared/data/envmaps/hdr (the four 1k HDR maps with suns).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}
BENCH=$BUILD/bench/bench_prefilter
OUT=$ROOT/bench/results/prefilter.md
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$BUILD/pocl-cache}
HDR=$ROOT/../shared/data/envmaps/hdr
[ -d "$HDR" ] || HDR=/work/shared/data/envmaps/hdr
[ -d "$HDR" ] || { echo "bench_prefilter.sh: no $HDR (the shared HDR maps)" >&2; exit 1; }
MAPS=("$HDR"/*.hdr "$HDR"/*.exr)
SUN=$HDR/venice_sunset_1k.hdr
tmp=$(mktemp)
{
  echo "# Prefiltered specular: accuracy and speed"
  echo
  echo "bench/bench_prefilter.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), PoCL CPU device; load average at the start $(cut -d' ' -f1 /proc/loadavg)."
  echo
  echo "## Accuracy: the cut (default) and the anchors' estimator (1024 samples) against the double brute force"
  echo
  echo "filament schedule, 256² base; relative error (max over channels) at 400 uniformly drawn texels per level plus the 64 nearest each map's brightest texel."
  echo
  "$BENCH" accuracy "${MAPS[@]}" --size 256 --schedule filament
  echo
  echo "## Equal error: the anchors' estimator from 256 to 16384 samples per texel beside the cut"
  echo
  "$BENCH" samples "$SUN" "$HDR/studio_small_03_1k.hdr" --size 256 --schedule filament
  echo
  echo "## Whole commands (warm program caches): wall time, CPU time, peak resident memory"
  echo
  echo '```'
  "$BENCH" timing "$SUN" --size 256 --schedule filament --runs 5
  "$BENCH" timing "$SUN" --size 1024 --schedule filament --runs 3
  "$BENCH" timing "$SUN" --size 256 --schedule filament --runs 5 -- --method sampled --samples 1024
  "$BENCH" timing "$SUN" --size 256 --schedule filament --runs 3 -- --method sampled --samples 16384
  "$BENCH" timing "$SUN" --size 1024 --schedule filament --runs 3 -- --method sampled --samples 1024
  echo '```'
} | tee "$tmp"
mv "$tmp" "$OUT"
echo "wrote $OUT" >&2
