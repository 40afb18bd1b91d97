#!/usr/bin/env bash
# prtbake transport beside Embree 3 on the same rays, in one run: the torus knot of the
# transport benchmark (102,400 vertices, 204,800 triangles), shadowed, order 3, 1024 cosine
# rays per vertex. Whole commands (wall and CPU time from /usr/bin/time), the coefficients
# compared (mean and max |ΔT_00|), prtbake rerun for bit-identity, and the cost of an
# interreflection bounce against the direct term. RUNS alternating pairs (default 5: this
# machine's speed wanders by 15-25 %, so each pair shares its conditions), summarised as
# the median of each and the per-pair speed ratios. Then the other products that trace through the
# same BVH and packet kernels, on the same knot (with a lightmap UV set): the per-vertex transport,
# the lightmap's AO (512², 256 rays per texel) and a 32³ probe grid (256 rays per probe), three
# alternating runs each, rays per second of their ray-tracing phase from their sidecars.
# Writes bench/results/embree.md.
#   bash bench/bench_embree.sh [BUILD]     (BUILD: default build/, with bench_embree built)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}
OUT=$ROOT/bench/results/embree.md
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$BUILD/pocl-cache}
work=$(mktemp -d /tmp/prtbake-bench-embree.XXXXXX)
trap 'rm -rf "$work"' EXIT
PRTBAKE=$BUILD/prtbake
EMBREE=$BUILD/bench/bench_embree
"$EMBREE" --write-knot "$work/knot.obj"
timed() {  # label, command...: prints "label wall_s cpu_s peak_MiB"
  local label=$1; shift
  /usr/bin/time -f "$label %e %U %S %M" -o "$work/time.txt" "$@" > "$work/out.txt" 2>&1 || { cat "$work/out.txt" >&2; exit 1; }
  awk '{printf "%s %.2f %.2f %.0f\n", $1, $2, $3 + $4, $5 / 1024}' "$work/time.txt"
}
# Warm-up: program caches and the file cache.
"$PRTBAKE" transport "$work/knot.obj" -o "$work/warm.npy" --samples 64 --quiet
results=()
RUNS=${RUNS:-5}
[ "$RUNS" -ge 3 ] || { echo "bench_embree.sh: RUNS must be at least 3" >&2; exit 2; }
for run in $(seq "$RUNS"); do
  results+=("$(timed "prtbake#$run" "$PRTBAKE" transport "$work/knot.obj" -o "$work/p$run.npy" --samples 1024 --quiet)")
  results+=("$(timed "embree#$run" "$EMBREE" "$work/knot.obj" "$work/e$run.npy" --samples 1024)")
done
results+=("$(timed "prtbake-1-bounce" "$PRTBAKE" transport "$work/knot.obj" -o "$work/ir.npy" --samples 1024 --mode interreflected --bounces 1 --bounce-tolerance 0 --quiet)")
# The same traversal in the other products (rays / the seconds of their tracing phase).
"$EMBREE" --write-knot "$work/knot_uv.obj" --uv
for run in 1 2 3; do
  "$PRTBAKE" transport "$work/knot_uv.obj" -o "$work/t$run.npy" --samples 256 --quiet
  "$PRTBAKE" lightmap "$work/knot_uv.obj" -o "$work/lm$run" --uv 0 --size 512 --samples 256 --products ao --quiet
  "$PRTBAKE" probes "$work/knot_uv.obj" -o "$work/pr$run" --resolution 32,32,32 --samples 256 --bounces 0 --quiet
done
traversal=$(/usr/bin/python3 - "$work" <<'PY'
import json, statistics, sys
w = sys.argv[1]
rows = [("`transport knot.obj --samples 256` (per vertex)", "t%d.json", lambda j: (j["samples"]["rays"], j["timings_s"]["kernels"])),
        ("`lightmap knot.obj --size 512 --samples 256 --products ao` (per texel)", "lm%d/lightmap.json",
         lambda j: (j["samples"]["rays"], j["timings"]["bake_seconds"])),
        ("`probes knot.obj --resolution 32,32,32 --samples 256 --bounces 0` (per probe)", "pr%d/probes.json",
         lambda j: (j["samples"]["rays"], j["timings_seconds"]["trace"]))]
print("| command | rays | tracing s (median) | rays/s (median) |")
print("|---|---|---|---|")
for label, name, get in rows:
    v = [get(json.load(open("%s/%s" % (w, name % run)))) for run in (1, 2, 3)]
    print("| %s | %.4g | %.3f | %.3g |" % (label, v[0][0], statistics.median(s for _, s in v), statistics.median(r / s for r, s in v)))
PY
)
compare=$(python3 - "$work/p1.npy" "$work/e1.npy" "$work/p2.npy" "$work/p3.npy" <<'PY'
import struct, sys
def load(path):
    b = open(path, 'rb').read()
    n = struct.unpack('<H', b[8:10])[0]
    header = b[10:10 + n].decode()
    shape = tuple(int(x) for x in header.split('(')[1].split(')')[0].split(',') if x.strip())
    data = b[10 + n:]
    return shape, struct.unpack('<%df' % (len(data) // 4), data)
sp, p = load(sys.argv[1]); se, e = load(sys.argv[2])
assert sp == se, (sp, se)
stride = 1
for s in sp[1:]: stride *= s
d = [abs(p[i] - e[i]) for i in range(0, len(p), stride)]
same = all(open(sys.argv[1], 'rb').read() == open(f, 'rb').read() for f in sys.argv[3:])
print("shape %s; T_00 mean |prtbake - embree| %.2e, max %.2e; prtbake reruns bit-identical: %s" % (sp, sum(d) / len(d), max(d), "yes" if same else "NO"))
PY
)
{
  echo "# Transport beside Embree 3: the knot, shadowed, order 3, 1024 rays per vertex"
  echo
  echo "bench/bench_embree.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)); Embree $(dpkg-query -W -f='${Version}' libembree-dev 2>/dev/null || echo '?') (rtcOccluded16, one thread per core), prtbake on PoCL's CPU device; warm program caches; $RUNS alternating runs of each."
  echo
  echo "| run | wall [s] | CPU [s] | peak [MiB] |"
  echo "|---|---|---|---|"
  for r in "${results[@]}"; do set -- $r; echo "| $1 | $2 | $3 | $4 |"; done
  echo
  printf '%s\n' "${results[@]}" | awk '
    $1 ~ /^prtbake#/ { p[++np] = $2 } $1 ~ /^embree#/ { e[++ne] = $2 }
    function median(a, n,   i, j, t) { for (i = 1; i <= n; ++i) for (j = i + 1; j <= n; ++j) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t } return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2 }
    END {
      r = ""; for (i = 1; i <= np; ++i) r = r sprintf("%s%.2f", i > 1 ? ", " : "", e[i] / p[i]);
      mp = median(p, np); me = median(e, ne);
      printf "Speed of prtbake against Embree (Embree wall / prtbake wall): %.2fx median against median (%.2f s against %.2f s); per pair %s.\n", me / mp, mp, me, r }'
  echo
  echo "Coefficients: $compare."
  echo
  echo "The bounce: \`prtbake-1-bounce\` is the interreflected command with one bounce (the same 1024 rays per vertex for the direct term and for the bounce); its cost beyond the direct term is its time minus the shadowed command's."
  echo
  echo "## The same traversal in the other products"
  echo
  echo "The knot again, with a lightmap UV set (\`bench_embree --write-knot knot.obj --uv\`: 8 charts), three alternating runs of each; tracing s: the transport's kernels, the lightmap's ray pass (bake_seconds: rasterising, moving samples out and the repairs apart), the probes' trace. The transport and the lightmap trace occlusion rays from the surface; the probes' rays start in the open, most of them outside the knot."
  echo
  echo "$traversal"
} > "$OUT"
cat "$OUT"
