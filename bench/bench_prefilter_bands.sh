#!/usr/bin/env bash
# `prtbake prefilter` of a large lat-long OpenEXR file with two builds side by side: one that
# reads the file whole (A) and one that reads it in bands (B). Two commands: the default
# chain (GGX, linear schedule, base 256) and `--lobe charlie --schedule filament --size 64`.
# RUNS rounds (default 5), each running both commands with A then B, so that each pair shares
# the machine's conditions; reported: median wall time and median peak resident memory (GNU
# time's maximum RSS) of each, and the per-pair ratio B/A. The last round's KTX2 files are
# compared byte for byte; where they differ, both builds run the command once more with
# --float32 for the largest relative difference per level. Replaces the section "Large
# lat-long files in bands" of bench/results/prefilter.md (or OUT).
#   bash bench/bench_prefilter_bands.sh A_PRTBAKE B_PRTBAKE [LATLONG.exr]
# Without LATLONG.exr, an 8192×4096 float32 map is written with build/bench/bench_env
# --write-latlong (BENCH_ENV to override).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
[ $# -ge 2 ] || { echo "usage: bench_prefilter_bands.sh A_PRTBAKE B_PRTBAKE [LATLONG.exr]" >&2; exit 2; }
A=$(realpath "$1") B=$(realpath "$2")
OUT=${OUT:-$ROOT/bench/results/prefilter.md}
RUNS=${RUNS:-5}
[ "$RUNS" -ge 3 ] || { echo "bench_prefilter_bands.sh: RUNS must be at least 3" >&2; exit 2; }
work=$(mktemp -d /tmp/prtbake-bench-bands.XXXXXX)
trap 'rm -rf "$work"' EXIT
if [ $# -ge 3 ]; then
  MAP=$(realpath "$3")
else
  MAP=$work/latlong.exr
  "${BENCH_ENV:-$ROOT/build/bench/bench_env}" --write-latlong "$MAP"
fi

declare -A args=([ggx]="" [charlie]="--lobe charlie --schedule filament --size 64")
# The warm-up builds each lobe's programs into the caches (a 4² chain: the same kernels).
declare -A warm=([ggx]="--size 4" [charlie]="--lobe charlie --size 4")
commands=(ggx charlie)
timed() {  # which (A|B), binary, command name, its arguments: prints "name:which wall_s peak_KiB"
  local which=$1 bin=$2 name=$3 extra=$4
  # shellcheck disable=SC2086
  POCL_CACHE_DIR=$work/cache-$which /usr/bin/time -f "$name:$which %e %M" -o "$work/time.txt" \
    "$bin" prefilter "$MAP" -o "$work/$which-$name.ktx2" $extra -q > "$work/out.txt" 2>&1 ||
    { cat "$work/out.txt" >&2; exit 1; }
  cat "$work/time.txt"
}
for name in "${commands[@]}"; do
  timed A "$A" "$name" "${warm[$name]}" > /dev/null
  timed B "$B" "$name" "${warm[$name]}" > /dev/null
done
lines=()
for round in $(seq "$RUNS"); do
  for name in "${commands[@]}"; do
    lines+=("$(timed A "$A" "$name" "${args[$name]}")")
    lines+=("$(timed B "$B" "$name" "${args[$name]}")")
  done
done
compare=()
for name in "${commands[@]}"; do
  if cmp -s "$work/A-$name.ktx2" "$work/B-$name.ktx2"; then
    compare+=("$name: the KTX2 files (RGBA16F) are identical byte for byte")
  else
    for which in A B; do
      bin=$A; [ $which = B ] && bin=$B
      # shellcheck disable=SC2086
      POCL_CACHE_DIR=$work/cache-$which "$bin" prefilter "$MAP" -o "$work/$which-$name-f32.ktx2" ${args[$name]} --float32 -q
    done
    compare+=("$name: $(/usr/bin/python3 - "$work/A-$name-f32.ktx2" "$work/B-$name-f32.ktx2" <<'PY'
import struct, sys
def levels(path):  # RGBA32F levels of a KTX2 file, as flat tuples
    b = open(path, "rb").read()
    count, = struct.unpack_from("<I", b, 40)
    out = []
    for i in range(count):
        off, length, _ = struct.unpack_from("<QQQ", b, 80 + 24 * i)
        out.append(struct.unpack_from("<%df" % (length // 4), b, off))
    return out
parts = []
for i, (x, y) in enumerate(zip(*map(levels, sys.argv[1:3]))):
    rel = max((abs(p - q) / max(abs(p), 1e-30) for p, q in zip(x, y)), default=0.0)
    parts.append("level %d max relative difference %.3g" % (i, rel))
print("; ".join(parts))
PY
)")
  fi
done
section=$work/section.md
{
  echo "## Large lat-long files in bands"
  echo
  echo "bench/bench_prefilter_bands.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), PoCL CPU device; load average at the start $(cut -d' ' -f1 /proc/loadavg). $RUNS rounds, each running both commands with A (the file read whole) then B (in bands), warm program caches:"
  echo
  echo '```'
  echo "A/prtbake prefilter $(basename "$MAP") -o OUT.ktx2 ARGS -q"
  echo "B/prtbake prefilter $(basename "$MAP") -o OUT.ktx2 ARGS -q"
  echo '```'
  echo
  echo "$(basename "$MAP"): $(stat -c %s "$MAP") bytes. A: $A; B: $B."
  echo
  echo "| command (ARGS) | A median [s] | B median [s] | B/A per pair, median (min–max) | A peak, median [MiB] | B peak, median [MiB] |"
  echo "|---|---|---|---|---|---|"
  printf '%s\n' "${lines[@]}" | awk -v ggx="(none: ggx, linear, 256)" -v charlie="${args[charlie]}" '
    function median(a, n,   i, j, t) { for (i = 1; i <= n; ++i) for (j = i + 1; j <= n; ++j) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t } return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2 }
    { split($1, k, ":"); c = k[1]; w = k[2]; n[c, w]++; t[c, w, n[c, w]] = $2; m[c, w, n[c, w]] = $3 / 1024; if (!(c in seen)) { seen[c] = 1; order[++nc] = c } }
    END {
      for (i = 1; i <= nc; ++i) { c = order[i]; r = n[c, "A"]; lo = 1e9; hi = 0
        for (j = 1; j <= r; ++j) { ta[j] = t[c, "A", j]; tb[j] = t[c, "B", j]; pa[j] = m[c, "A", j]; pb[j] = m[c, "B", j]
          q[j] = t[c, "B", j] / t[c, "A", j]; if (q[j] < lo) lo = q[j]; if (q[j] > hi) hi = q[j] }
        printf "| %s | %.2f | %.2f | %.3f (%.3f–%.3f) | %.0f | %.0f |\n", (c == "ggx" ? ggx : charlie), median(ta, r), median(tb, r), median(q, r), lo, hi, median(pa, r), median(pb, r) } }'
  echo
  echo "Outputs (the last round's):"
  echo
  for line in "${compare[@]}"; do echo "- $line"; done
} > "$section"
# The section replaces its previous version (from its heading to the next "## " heading).
awk -v file="$section" '
  /^## Large lat-long files in bands$/ { skip = 1; while ((getline l < file) > 0) print l; done = 1; next }
  skip && /^## / { skip = 0; print "" }
  !skip { print }
  END { if (!done) { print ""; while ((getline l < file) > 0) print l } }' "$OUT" > "$work/out.md"
cp "$work/out.md" "$OUT"
cat "$section"
