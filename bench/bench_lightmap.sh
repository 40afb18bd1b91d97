#!/usr/bin/env bash
# Lightmap speed on a ~100k-triangle scene (bench/lightmap_scene.py: a self-shadowing terrain with
# 16 pillars, one UV set): the AO bake's rays per second beside the per-vertex shadowed transport
# of the same scene at the same samples (both: rays / the kernels' seconds from the sidecars), and
# the whole command of a 1024² AO + bent-normal map at 256 rays per texel with its peak memory
# (/usr/bin/time). RUNS alternating runs of each, medians. Then the anchor, where Blender runs: its
# Cycles AO bake (bench/cycles_ao_bake.py) of the same UV set at ANCHOR_SIZE² beside prtbake's at
# 16, 64 and 256 samples per texel, each against its own 4096-sample bake (noise for time) and the
# two 4096-sample bakes against each other (agreement once converged). Writes bench/results/lightmap.md.
#   bash bench/bench_lightmap.sh [PRTBAKE]     (default build/prtbake; RUNS=3, ANCHOR_SIZE=256)
# Blender: Debian's blender package (apt-get install blender; not in CI), run headless.
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
ANCHOR_SIZE=${ANCHOR_SIZE:-256}
ANCHOR_SAMPLES="16 64 256 4096"
blender_version=none
if command -v blender >/dev/null 2>&1; then
  blender_version=$(blender --version 2>/dev/null | head -1)
  for s in $ANCHOR_SAMPLES; do
    /usr/bin/time -f "%e %M" -o t_pa_$s.txt "$PRTBAKE" lightmap scene.obj -o pa_$s --size "$ANCHOR_SIZE" --samples "$s" --products ao --quiet
    /usr/bin/time -f "%e %M" -o t_ca_$s.txt blender -b --factory-startup --python "$ROOT/bench/cycles_ao_bake.py" -- \
      scene.obj "$ANCHOR_SIZE" "$s" ca_$s.npy >ca_$s.log 2>&1
  done
else
  echo "bench_lightmap.sh: no blender on PATH: the anchor is left out" >&2
fi
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
PYTHONPATH=$(dirname "$PRTBAKE")/python${PYTHONPATH:+:$PYTHONPATH} "$PY" - "$RUNS" "$triangles" "$load_before" "$load_after" "$PRTBAKE" "$blender_version" "$ANCHOR_SIZE" "$ANCHOR_SAMPLES" >"$OUT" <<'PYEOF'
import json, os, statistics, subprocess, sys
runs, triangles, load_before, load_after, prtbake = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
blender, anchor_size, anchor_samples = sys.argv[6], int(sys.argv[7]), [int(s) for s in sys.argv[8].split()]
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
if blender == "none":
    print("## The anchor\n")
    print("Not measured in this run: Blender (its Cycles AO bake) was not on PATH.")
    sys.exit(0)
import numpy as np
import prtbake as pb
print("## The anchor: Blender's Cycles AO bake, side by side\n")
print("%s, `blender -b --factory-startup --python bench/cycles_ao_bake.py` (Render > Bake > Ambient Occlusion: "
      "the CPU device with every core, no denoising, AO distance beyond the scene, margin 8 texels extended) and "
      "`prtbake lightmap scene.obj --size %d --products ao --samples N`, the same OBJ and UV set at %d², one run each, "
      "alternating. prtbake's AO is cosine-weighted visibility over the whole scene (docs/lightmap.md); Cycles' AO "
      "bake is the same quantity.\n" % (blender, anchor_size, anchor_size))
ref = max(anchor_samples)
pa = pb.read_exr("pa_%d/ao.exr" % ref)
valid = pa["A"] > 0.5
# Interior texels: valid with all 8 neighbours valid, so that neither tool's edge handling
# (prtbake's conservative samples, Cycles' margin) enters the comparison.
interior = valid.copy()
for dy in (-1, 0, 1):
    for dx in (-1, 0, 1):
        interior &= np.roll(np.roll(valid, dy, 0), dx, 1)
interior[0, :] = interior[-1, :] = interior[:, 0] = interior[:, -1] = False
# The terrain's chart (UV [0.02, 0.98]²) apart from the pillars' strip, whose charts are 2.6 texels
# wide at 256²: there every texel is an edge texel, where the tools place their samples differently.
W = interior.shape[1]
u = (np.arange(W) + 0.5) / W
inside = (u > 0.02) & (u < 0.98)
terrain = interior & inside[None, :] & inside[:, None]
def prt(s): return pb.read_exr("pa_%d/ao.exr" % s)["Y"]
def cyc(s): return np.load("ca_%d.npy" % s)
def rms(a, b): return float(np.sqrt(np.mean((a[terrain] - b[terrain]) ** 2)))
def wall(name): return time_of(name)
def cycles_bake(s):
    for l in open("ca_%d.log" % s):
        if l.startswith("cycles_bake_seconds"): return float(l.split()[1])
    raise SystemExit("ca_%d.log: no cycles_bake_seconds (the bake failed)" % s)
pref, cref = prt(ref), cyc(ref)
print("Texels compared: the %d interior texels of the terrain's chart (valid with all eight neighbours valid; "
      "%d valid texels in all).\n" % (int(terrain.sum()), int(valid.sum())))
print("| samples per texel | prtbake wall s | prtbake bake s | prtbake peak MiB | prtbake RMS vs its %d | Cycles wall s | Cycles bake s | Cycles peak MiB | Cycles RMS vs its %d |" % (ref, ref))
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for s in anchor_samples:
    pw, pm = wall("t_pa_%d.txt" % s)
    cw, cm = wall("t_ca_%d.txt" % s)
    side = json.load(open("pa_%d/lightmap.json" % s))["timings"]
    pr = "%.4f" % rms(prt(s), pref) if s != ref else "(reference)"
    cr = "%.4f" % rms(cyc(s), cref) if s != ref else "(reference)"
    print("| %d | %.2f | %.2f | %.0f | %s | %.2f | %.2f | %.0f | %s |" % (s, pw, side["total_seconds"], pm, pr, cw, cycles_bake(s), cm, cr))
def bake_s(s): return json.load(open("pa_%d/lightmap.json" % s))["timings"]["total_seconds"]
for s in anchor_samples:
    if s != ref:
        print("\nAt %d samples per texel prtbake's bake took %.2f s against Cycles' %.2f s (%.1fx faster), with RMS noise %.4f "
              "against %.4f." % (s, bake_s(s), cycles_bake(s), cycles_bake(s) / bake_s(s), rms(prt(s), pref), rms(cyc(s), cref)), end="")
print("\nAt %d: %.2f s against %.2f s (%.1fx)." % (ref, bake_s(ref), cycles_bake(ref), cycles_bake(ref) / bake_s(ref)))
def agreement(mask):
    d = (cref - pref)[mask]
    return "mean %+.4f, RMS %.4f, 99th percentile of |Δ| %.4f, largest %.4f" % (
        float(d.mean()), float(np.sqrt(np.mean(d * d))), float(np.percentile(np.abs(d), 99)), float(np.abs(d).max()))
noise = (rms(prt(256), pref) ** 2 + rms(cyc(256), cref) ** 2) ** 0.5 * (256 / ref) ** 0.5 if 256 in anchor_samples else float("nan")
print("\nConverged agreement, Cycles − prtbake at %d samples: on the terrain's interior %s (the two references' "
      "noise together: about %.4f RMS, from the 256-sample rows scaled by √(256/%d)); on the pillars' strip "
      "(%d texels of 2.6-texel-wide charts) %s." % (ref, agreement(terrain), noise, ref, int((interior & ~terrain).sum()),
                                                   agreement(interior & ~terrain)))
print("\nBoth shade with the OBJ's normals (Cycles: smooth shading on the imported custom normals).")
print("\nprtbake's bake s: the command's own total (raster, unocclusion, rays, repairs) from lightmap.json; "
      "Cycles' bake s: `bpy.ops.object.bake` alone. The wall seconds include each program's start "
      "(Blender's and the OBJ import; prtbake's kernel cache warm).")
PYEOF
echo "bench_lightmap.sh: wrote $OUT" >&2
