#!/usr/bin/env bash
# Packs what bench/bench_gpu.sh needs on a bare GPU machine into DEST (default .gpu/ in the
# repository root, which this script adds to the main repository's .git/info/exclude):
#   bin/       prtbake and the benchmark programs of BUILD/bench but bench_embree (stripped copies)
#   lib/       every shared library they link that is neither glibc's, libstdc++/libgcc_s
#              nor the OpenCL ICD loader (OpenEXR, Iex, IlmThread, Imath, tinygltf,
#              tinyobjloader, stb, zlib)
#   lib-cxx/   libstdc++ and libgcc_s: used only when the machine's own are too old
#   lib-ocl/   ocl-icd's libOpenCL.so.1: used only when the machine has no ICD loader
#   data/      the inputs, laid out as ../shared/data: meshes/obj/mary.obj,
#              envmaps/hdr/venice_sunset_1k.hdr, envmaps/games202/Skybox2048/, and
#              knot.obj.gz (the transport benchmark's torus knot, makeTorusKnot(800, 128))
#   paths.env  the paths compiled into the benchmarks (PRTBAKE_CLI_PATH, PRTBAKE_BENCH_DATA_DIR)
#   bench_gpu.sh  a copy of bench/bench_gpu.sh (bash .gpu/bench_gpu.sh RESULTS, from the root)
# and prints the total size, which must stay under 55 MiB (the device copy carries 64 MiB).
#   bash bench/gpu_pack.sh [BUILD] [DEST]     (BUILD: default build/)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=$(cd "${1:-$ROOT/build}" && pwd)
DEST=${2:-$ROOT/.gpu}
DATA=${PRTBAKE_DATA_DIR:-$(sed -n 's/^PRTBAKE_DATA_DIR:PATH=//p' "$BUILD/CMakeCache.txt")}
[ -x "$BUILD/prtbake" ] || { echo "gpu_pack.sh: $BUILD/prtbake is not built" >&2; exit 2; }
[ -d "$DATA" ] || { echo "gpu_pack.sh: data folder $DATA is absent" >&2; exit 2; }

exclude=$(git -C "$ROOT" rev-parse --path-format=absolute --git-common-dir)/info/exclude
mkdir -p "$(dirname "$exclude")"
grep -qxF '/.gpu/' "$exclude" 2>/dev/null || echo '/.gpu/' >> "$exclude"

rm -rf "$DEST"
mkdir -p "$DEST"/{bin,lib,lib-cxx,lib-ocl,data}
bins=("$BUILD/prtbake")
# (bench_embree, the CPU peer of bench_embree.sh, stays: Embree alone is 44 MB.)
for b in "$BUILD"/bench/bench_*; do [ -x "$b" ] && [ -f "$b" ] && [ "${b##*/}" != bench_embree ] && bins+=("$b"); done
for b in "${bins[@]}"; do
  cp "$b" "$DEST/bin/"
  strip --strip-unneeded "$DEST/bin/$(basename "$b")" 2>/dev/null || true
done

# Shared libraries, by the name each binary asks for (the soname), copied through links.
for b in "${bins[@]}"; do ldd "$b"; done | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' | sort -u |
  while read -r name path; do
    case $name in
      libc.so.*|libm.so.*|libpthread.so.*|libdl.so.*|librt.so.*|libresolv.so.*|ld-linux*|libmvec.so.*) continue ;;
      libstdc++.so.*|libgcc_s.so.*) dir=lib-cxx ;;
      libOpenCL.so.*) dir=lib-ocl ;;
      *) dir=lib ;;
    esac
    cp -L "$path" "$DEST/$dir/$name"
  done

# The benchmark script itself: `bash .gpu/bench_gpu.sh RESULTS` runs from the pack alone
# (its repository root is the folder above it) on a checkout that lacks bench/bench_gpu.sh.
cp "$ROOT/bench/bench_gpu.sh" "$DEST/"

# Inputs.
mkdir -p "$DEST/data/meshes/obj" "$DEST/data/envmaps/hdr" "$DEST/data/envmaps/games202"
cp "$DATA/meshes/obj/mary.obj" "$DEST/data/meshes/obj/"
cp "$DATA/envmaps/hdr/venice_sunset_1k.hdr" "$DEST/data/envmaps/hdr/"
cp -r "$DATA/envmaps/games202/Skybox2048" "$DEST/data/envmaps/games202/"
chmod -R u+w "$DEST/data"

# The torus knot of bench_embree --write-knot (makeTorusKnot(800, 128), host/src/geometry/mesh.cpp):
# from bench_embree when it is built, else the same construction in Python (double
# arithmetic, float32 vertices, printed with %.9g as bench_embree writes them).
if [ -x "$BUILD/bench/bench_embree" ]; then
  "$BUILD/bench/bench_embree" --write-knot "$DEST/data/knot.obj"
else
  python3 - "$DEST/data/knot.obj" <<'PY'
import math, struct, sys
def f32(x): return struct.unpack('f', struct.pack('f', x))[0]
segments, sides, p, q, radius = 800, 128, 2, 3, 0.4
pi = 3.14159265358979323846
def curve(t):
    r = 2 + math.cos(q * t)
    return [r * math.cos(p * t), r * math.sin(p * t), math.sin(q * t)]
def normalize(v):
    l = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return [x / l for x in v]
pos, nrm = [], []
for i in range(segments):
    t, h = 2 * pi * i / segments, 1e-4
    c0, cm, cp = curve(t), curve(t - h), curve(t + h)
    T = [cp[k] - cm[k] for k in range(3)]
    A = [cp[k] - 2 * c0[k] + cm[k] for k in range(3)]
    T = normalize(T)
    ta = T[0] * A[0] + T[1] * A[1] + T[2] * A[2]
    N = normalize([A[k] - ta * T[k] for k in range(3)])
    B = [T[1] * N[2] - T[2] * N[1], T[2] * N[0] - T[0] * N[2], T[0] * N[1] - T[1] * N[0]]
    for j in range(sides):
        a = 2 * pi * j / sides
        ca, sa = math.cos(a), math.sin(a)
        n = [ca * N[k] + sa * B[k] for k in range(3)]
        pos.append([f32(c0[k] + radius * n[k]) for k in range(3)])
        nrm.append([f32(x) for x in n])
with open(sys.argv[1], 'w') as out:
    for v in pos: out.write('v %.9g %.9g %.9g\n' % tuple(v))
    for v in nrm: out.write('vn %.9g %.9g %.9g\n' % tuple(v))
    for i in range(segments):
        for j in range(sides):
            a = i * sides + j + 1
            b = i * sides + (j + 1) % sides + 1
            c = ((i + 1) % segments) * sides + (j + 1) % sides + 1
            d = ((i + 1) % segments) * sides + j + 1
            out.write('f %d//%d %d//%d %d//%d\n' % (a, a, b, b, c, c))
            out.write('f %d//%d %d//%d %d//%d\n' % (a, a, c, c, d, d))
PY
fi
gzip -9 -f "$DEST/data/knot.obj"

{
  echo "# Paths compiled into the benchmark programs (bench/CMakeLists.txt), from $BUILD."
  printf 'PRTBAKE_CLI_PATH=%q\n' "$BUILD/prtbake"
  printf 'PRTBAKE_BENCH_DATA_DIR=%q\n' "$DATA"
  printf 'PACKED_FROM=%q\n' "$(git -C "$ROOT" rev-parse --short HEAD) $(date -u +%Y-%m-%dT%H:%MZ)"
} > "$DEST/paths.env"
grep -qF "$BUILD/prtbake" "$DEST/bin/bench_lut" ||
  echo "gpu_pack.sh: warning: bench_lut does not hold $BUILD/prtbake as its CLI path" >&2

(cd "$DEST" && find . -type f | sort | xargs ls -l | awk '{printf "%10d  %s\n", $5, $9}')
bytes=$(du -sb "$DEST" | cut -f1)
echo "total $(awk -v b="$bytes" 'BEGIN {printf "%.1f MiB", b / 1048576}') in $DEST"
if [ "$bytes" -ge $((55 * 1048576)) ]; then
  echo "gpu_pack.sh: $DEST is over 55 MiB" >&2
  exit 1
fi
