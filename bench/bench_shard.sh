#!/usr/bin/env bash
# Sharding overhead: one large split transport job run as 1 process, and as N = 2, 4, 8
# shards run one after another and two at a time, plus the merge.
#   bench/bench_shard.sh [PRTBAKE] [WORKDIR]     (prints a Markdown table)
# The mesh is generated (a UV sphere on a ground plane, ~20k vertices); samples 2048.
# Sequential shards measure the pure overhead (every shard repeats process and OpenCL
# start-up, mesh load, ray set-up and the BVH build); two at a time shows what 2 cores
# give when each shard's PoCL device already uses both.
set -euo pipefail
exe=${1:-$(dirname "$0")/../build/prtbake}
exe=$(cd "$(dirname "$exe")" && pwd)/$(basename "$exe")
work=${2:-$(mktemp -d /tmp/prtbake-bench-shard.XXXXXX)}
mkdir -p "$work" && cd "$work"
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$work/pocl-cache}
rings=${RINGS:-140}; segments=${SEGMENTS:-141}; samples=${SAMPLES:-2048}

awk -v R="$rings" -v S="$segments" 'BEGIN {
  pi = 3.14159265358979323846
  for (i = 0; i <= R; i++) for (j = 0; j < S; j++) {
    th = pi * i / R; ph = 2 * pi * j / S
    x = sin(th) * cos(ph); y = cos(th); z = sin(th) * sin(ph)
    printf "v %.6f %.6f %.6f\nvn %.6f %.6f %.6f\n", x, y + 1, z, x, y, z
  }
  for (i = 0; i < R; i++) for (j = 0; j < S; j++) {
    a = i * S + j + 1; b = i * S + (j + 1) % S + 1; c = a + S; d = b + S
    printf "f %d//%d %d//%d %d//%d\nf %d//%d %d//%d %d//%d\n", a, a, b, b, d, d, a, a, d, d, c, c
  }
  base = (R + 1) * S; G = 9
  for (i = 0; i < G; i++) for (j = 0; j < G; j++) printf "v %.6f 0 %.6f\nvn 0 1 0\n", -3 + 6 * i / (G - 1), -3 + 6 * j / (G - 1)
  for (i = 0; i < G - 1; i++) for (j = 0; j < G - 1; j++) {
    a = base + i * G + j + 1; b = a + 1; c = a + G; d = c + 1
    printf "f %d//%d %d//%d %d//%d\nf %d//%d %d//%d %d//%d\n", a, a, b, b, d, d, a, a, d, d, c, c
  }
}' > scene.obj
vertices=$(grep -c '^v ' scene.obj)

jobfile() {  # jobfile NAME OUTDIR
  printf '{"jobs": [{"id": "scene", "type": "transport", "input": "scene.obj", "split": true, "samples": %s, "outputs": {"npy": "%s/scene.npy"}}]}\n' "$samples" "$2" > "$1"
}
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

jobfile warm.json warm && "$exe" run warm.json --quiet --force   # fills the kernel cache
jobfile one.json one
t0=$(now); "$exe" run one.json --quiet --force; t1=$(now)
single=$(secs "$t0" "$t1")

echo "| run | wall s | vs 1 process |"
echo "|---|---|---|"
echo "| 1 process | $single | 1.00 |"
for n in 2 4 8; do
  jobfile "s$n.json" "s$n"
  t0=$(now)
  for ((i = 0; i < n; i++)); do "$exe" run "s$n.json" --quiet --force --shard "$i/$n"; done
  t1=$(now)
  seq=$(secs "$t0" "$t1")
  jobfile "p$n.json" "p$n"
  t0=$(now)
  seq 0 $((n - 1)) | xargs -P 2 -I{} "$exe" run "p$n.json" --quiet --force --shard "{}/$n"
  t1=$(now)
  par=$(secs "$t0" "$t1")
  t0=$(now); "$exe" merge "s$n.json" --shards "$n" --quiet; t1=$(now)
  merge=$(secs "$t0" "$t1")
  cmp -s one/scene.npy "s$n/scene.npy" || { echo "merged result of $n shards differs" >&2; exit 1; }
  echo "| $n shards, one after another | $seq | $(awk -v a="$seq" -v b="$single" 'BEGIN { printf "%.2f", a / b }') |"
  echo "| $n shards, two at a time | $par | $(awk -v a="$par" -v b="$single" 'BEGIN { printf "%.2f", a / b }') |"
  echo "| merge of $n | $merge | $(awk -v a="$merge" -v b="$single" 'BEGIN { printf "%.2f", a / b }') |"
done
echo
echo "mesh: $vertices vertices, $samples samples per vertex; $(nproc) cores; merged results byte-identical to the 1-process run"
