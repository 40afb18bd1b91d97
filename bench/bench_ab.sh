#!/usr/bin/env bash
# Two builds of prtbake side by side on the same whole commands, for a change that must not
# cost speed (a refactor, a compiler flag): transport on the knot of bench_embree.sh
# (204,800 triangles, shadowed, order 3, 1024 rays per vertex), `env` on Skybox2048 (six
# 2048² JPEGs) and on an 8192×4096 float lat-long OpenEXR, and the cold start of `lut` and of
# `transport mary.obj` (an empty program cache each). RUNS rounds (default 5); in each round
# every command runs with A then B, so that each pair shares the machine's conditions.
# Reported: the median of each and the median of the per-pair ratios B/A (below 1: B faster).
# Both builds' outputs are compared byte for byte. Writes bench/results/ab.md (or OUT).
#   bash bench/bench_ab.sh A_PRTBAKE B_PRTBAKE [LABEL_A LABEL_B]
# The knot and the lat-long come from build/bench/bench_embree --write-knot and
# build/bench/bench_env --write-latlong (BENCH_EMBREE, BENCH_ENV to override).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
[ $# -ge 2 ] || { echo "usage: bench_ab.sh A_PRTBAKE B_PRTBAKE [LABEL_A LABEL_B]" >&2; exit 2; }
A=$(realpath "$1") B=$(realpath "$2")
LABEL_A=${3:-A} LABEL_B=${4:-B}
OUT=${OUT:-$ROOT/bench/results/ab.md}
DATA=${PRTBAKE_DATA_DIR:-$ROOT/../shared/data}
SKY=$DATA/envmaps/games202/Skybox2048
MARY=$DATA/meshes/obj/mary.obj
EMBREE=${BENCH_EMBREE:-$ROOT/build/bench/bench_embree}
BENCH_ENV=${BENCH_ENV:-$ROOT/build/bench/bench_env}
for f in "$SKY" "$MARY" "$EMBREE" "$BENCH_ENV"; do
  [ -e "$f" ] || { echo "bench_ab.sh: $f is absent: nothing measured" >&2; exit 2; }
done
RUNS=${RUNS:-5}
[ "$RUNS" -ge 3 ] || { echo "bench_ab.sh: RUNS must be at least 3" >&2; exit 2; }
work=$(mktemp -d /tmp/prtbake-bench-ab.XXXXXX)
trap 'rm -rf "$work"' EXIT
"$EMBREE" --write-knot "$work/knot.obj"
"$BENCH_ENV" --write-latlong "$work/latlong.exr"

timed() {  # label, cache dir, output dir, command...: prints "label wall_s peak_MiB"
  local label=$1 cache=$2 dir=$3; shift 3
  mkdir -p "$dir"
  (cd "$dir" && POCL_CACHE_DIR=$cache /usr/bin/time -f "$label %e %M" -o "$work/time.txt" "$@" > "$work/out.txt" 2>&1) ||
    { cat "$work/out.txt" >&2; exit 1; }
  awk '{printf "%s %.2f %.0f\n", $1, $2, $3 / 1024}' "$work/time.txt"
}
commands=(knot sky latlong lut_cold mary_cold)
run_one() {  # which (A|B), binary, command name, round: one timed line
  local which=$1 bin=$2 name=$3 round=$4 dir=$work/$1/$3 cache=$work/cache-$1
  case $name in
    knot) timed "$name:$which" "$cache" "$dir" "$bin" transport "$work/knot.obj" -o knot.npy --samples 1024 --quiet ;;
    sky) timed "$name:$which" "$cache" "$dir" "$bin" env "$SKY" -o sky.json --quiet ;;
    latlong) timed "$name:$which" "$cache" "$dir" "$bin" env "$work/latlong.exr" -o latlong.json --quiet ;;
    lut_cold) rm -rf "$work/cold-$which"; mkdir "$work/cold-$which"
      timed "$name:$which" "$work/cold-$which" "$dir" "$bin" lut -o lut.exr --quiet ;;
    mary_cold) rm -rf "$work/cold-$which"; mkdir "$work/cold-$which"
      timed "$name:$which" "$work/cold-$which" "$dir" "$bin" transport "$MARY" -o mary.npy --quiet ;;
  esac
}
# Warm-up: both program caches and the file cache.
for which in A B; do
  bin=$A; [ $which = B ] && bin=$B
  for name in knot sky latlong; do run_one $which "$bin" $name 0 > /dev/null; done
done
lines=()
for round in $(seq "$RUNS"); do
  for name in "${commands[@]}"; do
    lines+=("$(run_one A "$A" "$name" "$round")")
    lines+=("$(run_one B "$B" "$name" "$round")")
  done
done
same=()
for name in "${commands[@]}"; do
  differ=()
  for f in "$work/A/$name"/*; do
    g=$work/B/$name/$(basename "$f")
    case $f in *.json) # timings and the build's own details differ: compare the results only
      /usr/bin/python3 - "$f" "$g" <<'PY' || differ+=("$(basename "$f")")
import json, sys
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items()
                if not k.endswith("_s") and not any(s in k for s in ("time", "second", "version", "date"))}
    if isinstance(v, list): return [strip(x) for x in v]
    return v
a, b = (strip(json.load(open(p))) for p in sys.argv[1:3])
sys.exit(0 if a == b else 1)
PY
      ;;
    *) cmp -s "$f" "$g" || differ+=("$(basename "$f")") ;;
    esac
  done
  if [ ${#differ[@]} -eq 0 ]; then same+=("$name identical"); else same+=("$name DIFFERENT: ${differ[*]}"); fi
done
{
  echo "# $LABEL_B beside $LABEL_A: whole commands, alternating pairs"
  echo
  echo "bench/bench_ab.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)); PoCL $(dpkg-query -W -f='${Version}' pocl-opencl-icd 2>/dev/null || echo '?'), CPU device; $RUNS rounds, each running every command with $LABEL_A then $LABEL_B."
  echo
  echo "| command | $LABEL_A median [s] | $LABEL_B median [s] | B/A per pair, median (min–max) | $LABEL_A peak [MiB] | $LABEL_B peak [MiB] | outputs |"
  echo "|---|---|---|---|---|---|---|"
  printf '%s\n' "${lines[@]}" | awk -v same="$(printf '%s;' "${same[@]}")" '
    function median(a, n,   i, j, t) { for (i = 1; i <= n; ++i) for (j = i + 1; j <= n; ++j) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t } return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2 }
    { split($1, k, ":"); c = k[1]; w = k[2]; n[c, w]++; t[c, w, n[c, w]] = $2; if ($3 > peak[c, w]) peak[c, w] = $3; if (!(c in seen)) { seen[c] = 1; order[++nc] = c } }
    END {
      m = split(same, s, ";"); for (i = 1; i <= m; ++i) { split(s[i], f, " "); verdict[f[1]] = substr(s[i], length(f[1]) + 2) }
      for (i = 1; i <= nc; ++i) { c = order[i]; r = n[c, "A"]
        lo = 1e9; hi = 0
        for (j = 1; j <= r; ++j) { va[j] = t[c, "A", j]; vb[j] = t[c, "B", j]; q[j] = t[c, "B", j] / t[c, "A", j]; if (q[j] < lo) lo = q[j]; if (q[j] > hi) hi = q[j] }
        printf "| %s | %.2f | %.2f | %.3f (%.3f–%.3f) | %d | %d | %s |\n", c, median(va, r), median(vb, r), median(q, r), lo, hi, peak[c, "A"], peak[c, "B"], verdict[c] } }'
  echo
  echo "knot: \`transport knot.obj --samples 1024\` (the knot of bench_embree.sh); sky: \`env\` on games202/Skybox2048;"
  echo "latlong: \`env\` on an 8192×4096 float32 lat-long OpenEXR made for the run; lut_cold, mary_cold: \`lut\` and"
  echo "\`transport mary.obj\` with their defaults and an empty PoCL cache (program builds included)."
  echo "Outputs: the two builds' files compared byte for byte (JSON sidecars without their timings and build details)."
} > "$OUT"
cat "$OUT"
