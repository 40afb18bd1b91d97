#!/usr/bin/env bash
# Lightmap speed on a ~100k-triangle scene (bench/lightmap_scene.py: a self-shadowing terrain with
# 16 pillars, one UV set): the AO bake's rays per second beside the per-vertex shadowed transport
# of the same scene at the same samples (both: rays / the kernels' seconds from the sidecars), and
# the whole command of a 1024² AO + bent-normal map at 256 rays per texel with its peak memory
# (/usr/bin/time). RUNS alternating runs of each, medians. Writes bench/results/lightmap.md.
#   bash bench/bench_lightmap.sh [PRTBAKE]     (default build/prtbake; RUNS=3)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PRTBAKE=$(realpath "${1:-$ROOT/build/prtbake}")
OUT=$ROOT/bench/results/lightmap.md
RUNS=${RUNS:-3}
PY=/usr/bin/python3
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$(dirname "$PRTBAKE")/pocl-cache}
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
work=$(mktemp -d /tmp/prtbake-bench-lightmap.XXXXXX)
trap 'rm -rf "$work"' EXIT
cd "$work"
triangles=$("$PY" "$ROOT/bench/lightmap_scene.py" scene.obj | awk '/^triangles/ {print $2}')
# Warm the kernel caches.
"$PRTBAKE" transport scene.obj -o warm.npy --samples 16 --quiet
"$PRTBAKE" lightmap scene.obj -o warm --size 64 --samples 16 --products ao,bent --quiet
for r in $(seq "$RUNS"); do
  /usr/bin/time -f "%e %M" -o t_transport_$r.txt "$PRTBAKE" transport scene.obj -o tr_$r.npy --mode shadowed --samples 256 --quiet
  /usr/bin/time -f "%e %M" -o t_lightmap_$r.txt "$PRTBAKE" lightmap scene.obj -o lm_$r --size 1024 --samples 256 \
    --products ao,bent --quiet
done
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
"$PY" - "$RUNS" "$triangles" "$load_before" "$load_after" "$PRTBAKE" >"$OUT" <<'PYEOF'
import json, statistics, subprocess, sys
runs, triangles, load_before, load_after, prtbake = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
def time_of(name):
    wall, kib = open(name).read().split()
    return float(wall), int(kib) / 1024
tr, lm = [], []
for r in range(1, runs + 1):
    t = json.load(open("tr_%d.json" % r))
    w, mib = time_of("t_transport_%d.txt" % r)
    tr.append({"rays": t["samples"]["rays"], "kernel": t["timings_s"]["kernels"], "wall": w, "mib": mib,
               "unocc": t["samples"]["vertices_unoccludable"]})
    s = json.load(open("lm_%d/lightmap.json" % r))
    w, mib = time_of("t_lightmap_%d.txt" % r)
    lm.append({"rays": s["samples"]["rays"], "bake": s["timings"]["bake_seconds"], "wall": w, "mib": mib,
               "texels": s["texels"], "t": s["timings"]})
med = statistics.median
tr_rate = med([x["rays"] / x["kernel"] for x in tr])
lm_rate = med([x["rays"] / x["bake"] for x in lm])
cpu = [l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")]
print("# Lightmap benchmark\n")
print("`bash bench/bench_lightmap.sh` (%d alternating runs of each command, medians). Machine: %s, %d cores; "
      "load average %s before, %s after. Device: PoCL on the CPU.\n" % (runs, cpu[0] if cpu else "?", len(cpu), load_before, load_after))
print("Scene: `bench/lightmap_scene.py`, %d triangles: a self-shadowing terrain (220 x 220 quads, one chart) "
      "and 16 pillars (each face its own chart), OBJ with `vt`.\n" % triangles)
print("## Rays per second: the AO bake against the per-vertex shadowed transport\n")
print("Both trace the transport's cosine-distributed rays (256 per point) through the same packet kernels "
      "over the same BVH (the lightmap: one order-2 shadowed pass serves ao and bent; the unocclusion pass, 9 short rays per texel, is timed apart below).\n")
print("| command | rays (median) | kernel s (median) | rays/s (median) |")
print("|---|---:|---:|---:|")
print("| `transport scene.obj --mode shadowed --samples 256` | %.4g | %.3f | %.4g |" % (med([x["rays"] for x in tr]), med([x["kernel"] for x in tr]), tr_rate))
print("| `lightmap scene.obj --size 1024 --samples 256 --products ao,bent` | %.4g | %.3f | %.4g |" % (med([x["rays"] for x in lm]), med([x["bake"] for x in lm]), lm_rate))
print("\nRatio (lightmap / transport): **%.2f** (target ≥ 0.9).\n" % (lm_rate / tr_rate))
print("## The whole command: 1024² AO + bent normals at 256 rays per texel\n")
print("| run | wall s | peak MiB | raster s | unocclude s | bake s | repair s | baked | moved | buried | dilated |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for i, x in enumerate(lm):
    t, c = x["t"], x["texels"]
    print("| %d | %.2f | %.0f | %.2f | %.2f | %.2f | %.2f | %d | %d | %d | %d |" % (i + 1, x["wall"], x["mib"], t["raster_seconds"],
          t["unocclude_seconds"], t["bake_seconds"], t["repair_seconds"], c["baked"], c["moved"], c["buried"], c["dilated"]))
print("\nMedian: **%.2f s**, **%.0f MiB** peak. The per-vertex transport's whole command: %.2f s, %.0f MiB.\n"
      % (med([x["wall"] for x in lm]), med([x["mib"] for x in lm]), med([x["wall"] for x in tr]), med([x["mib"] for x in tr])))
print("## Not measured yet\n")
print("The anchor beside prtbake (three.js's progressive lightmapper in headless Chromium, or Blender's Cycles "
      "AO bake where it runs) on the same scene, cost and quality: the next step of this benchmark.")
PYEOF
echo "bench_lightmap.sh: wrote $OUT" >&2
