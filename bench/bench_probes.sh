#!/usr/bin/env bash
# prtbake's probe grids beside three.js r187's own baker (LightProbeGridWebGL.bake) in headless
# Chromium, on the same scene under the same sky, and the speed line of the 32 x 16 x 32 grid.
#
# The scene (bench/probes_scene.py, 100k triangles): a lit room open to the sky and a dark room
# with one small window, side by side, split by a 0.1 m wall. Both bakers compute the same
# quantity: the sky's radiance through the scene's visibility, projected to L2 SH, the surfaces
# black (prtbake --bounces 0; three: black MeshBasicMaterial, front faces only, no bounce pass).
# The sky is a degree-2 polynomial: prtbake gets its exact SH (sky.json), three the same
# function per texel of a float equirect background. Steps:
#   1. sanity: three's bake of the empty scene must give the sky's coefficients back;
#   2. the main grid (16 x 8 x 16 over the inside): prtbake at --samples 16 ... 16384 (seed 0),
#      three at each cube size of CUBES, both against prtbake at --samples 65536 (seed 1);
#   3. the slab: the 2 x 16 x 16 probes of the 32 x 16 x 32 grid nearest the thin wall (0.075 m
#      from its faces, closer than three's default near plane of 0.1 m), the same way;
#   4. the speed line: 32 x 16 x 32 at --samples 256, bounces 0 and 1, three runs each.
# Writes bench/results/probes.md. Needs chromium, node and tests/js/node_modules (npm ci in tests/js).
#   bash bench/bench_probes.sh [PRTBAKE]     (default build/prtbake)
#   CUBES='[8,16,32]' SLAB_CUBES='[8]' to change three's cube sizes; KEEP_WORK=1 keeps the temp dir.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PRTBAKE=$(realpath "${1:-$ROOT/build/prtbake}")
OUT=$ROOT/bench/results/probes.md
CUBES=${CUBES:-[8,16,32,64]}
SLAB_CUBES=${SLAB_CUBES:-[8,32]}
PY=/usr/bin/python3
THREE=$ROOT/tests/js/node_modules/three
CHROMIUM=$(command -v chromium || command -v chromium-browser || true)
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$(dirname "$PRTBAKE")/pocl-cache}
fail() { echo "bench_probes.sh: $*" >&2; exit 1; }
[ -x "$PRTBAKE" ] || fail "no prtbake at $PRTBAKE"
[ -n "$CHROMIUM" ] || fail "chromium not found"
[ -f "$THREE/package.json" ] || fail "three.js not installed ($THREE): npm ci in tests/js"
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
work=$(mktemp -d /tmp/prtbake-bench-probes.XXXXXX)
[ -n "${KEEP_WORK:-}" ] && echo "bench_probes.sh: keeping $work" >&2 || trap 'rm -rf "$work"' EXIT
cd "$work"

triangles=$("$PY" "$ROOT/bench/probes_scene.py" "$work" | awk '/^triangles/ {print $2}')
BOUNDS=-4,0,-4,4,4,4
echo '{"res": [16, 8, 16], "min": [-4, 0, -4], "max": [4, 4, 4]}' > main_grid.json
# The 32 x 16 x 32 grid's columns x = +-0.125 (cells 0.25 m), rows z = -1.875 ... 1.875.
echo '{"res": [2, 16, 16], "min": [-0.25, 0, -2], "max": [0.25, 4, 2]}' > slab_grid.json

bake() {  # DIR, then prtbake probes options (--bounces 0 unless BOUNCES is set): the whole command
  local dir=$1; shift  # under /usr/bin/time into DIR/time.txt
  mkdir -p "$dir"
  /usr/bin/time -f "%e %M" -o "$work/time.txt" "$PRTBAKE" probes rooms.gltf -o "$dir" --env sky.json --bounces "${BOUNCES:-0}" --quiet "$@" \
    > "$work/log.txt" 2>&1 || { cat "$work/log.txt" >&2; fail "prtbake probes $* failed"; }
  mv "$work/time.txt" "$dir/time.txt"
  echo "prtbake probes $* -> $(cat "$dir/time.txt")" >&2
}
three() {  # NAME, SCENE, GRID file, CUBES, SECONDS: three.js's bake in Chromium into three_NAME.out
  "$PY" "$ROOT/bench/probes_compare.py" page "$ROOT/bench/probes_three.html" "$THREE" "$2" sky_poly.json "$(cat "$3")" "$4" 0.1 \
    "$work/three_$1.html"
  PRTBAKE_CHROMIUM_PROFILE="$work/profile_$1" timeout $(($5 + 30)) node "$ROOT/tests/js/chromium_page.mjs" "$CHROMIUM" \
    "file://$work/three_$1.html" "$5" > "three_$1.out" || fail "three.js page $1: $(head -c 2000 "three_$1.out")"
  grep -q '^RESULT {' "three_$1.out" || fail "three.js page $1: $(head -c 2000 "three_$1.out")"
  echo "three.js $1: $(grep -o '"cubemapSize":[0-9]*,"seconds":[0-9.]*' "three_$1.out" | tr '\n' ' ')" >&2
}

bake warm --resolution 2,2,2 --bounds "$BOUNDS" --samples 16  # program caches, file cache
BOUNCES=1 bake warm1 --resolution 2,2,2 --bounds "$BOUNDS" --samples 16 --transport-samples 16
echo '{"res": [1, 1, 1], "min": [-1, -1, -1], "max": [1, 1, 1]}' > empty_grid.json
three empty "" empty_grid.json "[8,16,32,64]" 600
for name in main slab; do
  b=$("$PY" -c 'import json,sys; g=json.load(open(sys.argv[1])); print(",".join(map(str, g["min"] + g["max"])))' ${name}_grid.json)
  r=$("$PY" -c 'import json,sys; print(",".join(map(str, json.load(open(sys.argv[1]))["res"])))' ${name}_grid.json)
  bake ${name}_ref --resolution "$r" --bounds "$b" --samples 65536 --seed 1
  for s in 16 64 256 1024 4096 16384; do bake ${name}_s$s --resolution "$r" --bounds "$b" --samples $s; done
done
three main rooms.gltf main_grid.json "$CUBES" 3000
three slab rooms.gltf slab_grid.json "$SLAB_CUBES" 3000
for run in 1 2 3; do
  bake speed_b0_$run --resolution 32,16,32 --bounds "$BOUNDS" --samples 256
  BOUNCES=1 bake speed_b1_$run --resolution 32,16,32 --bounds "$BOUNDS" --samples 256
done
tables=$("$PY" "$ROOT/bench/probes_compare.py" report "$work") || fail "report: $tables"

{
  echo "# Probe grids: prtbake beside three.js's own baker"
  echo
  echo "bench/bench_probes.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), load average before the runs $load_before, after them $(cut -d' ' -f1-3 /proc/loadavg); $("$PRTBAKE" --version 2>/dev/null | head -1) on $("$PY" -c 'import json; print(json.load(open("main_s256/probes.json"))["device"])'); three.js $("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["version"])' "$THREE/package.json") in $("$CHROMIUM" --version 2>/dev/null | head -1) (headless, WebGL 2 on SwiftShader: both bakers on the CPU)."
  echo
  echo "Scene: bench/probes_scene.py, $triangles triangles: the inside x, z in [-4, 4] m, y in [0, 4] m, a 0.1 m wall at x = 0 between the lit room (x < 0, no ceiling) and the dark room (x > 0, a ceiling, one 0.8 m window in its far wall); a torus knot, pillars and spheres, one glTF mesh each. Sky: a degree-2 polynomial (exact order-3 SH for prtbake, a 1024 × 512 float equirect for three). Surfaces black in both (prtbake \`--bounces 0\`; three black \`MeshBasicMaterial\`, \`FrontSide\`, bake without bounce passes, near 0.1, far 100)."
  echo
  echo "Commands: \`prtbake probes rooms.gltf -o DIR --env sky.json --bounces 0 --resolution R --bounds B --samples S\`; three: \`new LightProbeGridWebGL(w, h, d, NX, NY, NZ)\` at the box's centre, \`grid.bake(renderer, scene, {cubemapSize, near: 0.1, far: 100})\` (bench/probes_three.html)."
  echo
  echo "$tables"
} > "$OUT"
cat "$OUT"
