#!/usr/bin/env bash
# Golden outputs: runs a fixed set of prtbake commands on the demo inputs (assets/) and
# prints the SHA-256 of every output, so that a change meant not to change any output (a
# refactor) can show that it did not:
#   bash scripts/golden.sh [PRTBAKE] > before.txt     (default build/prtbake)
#   ... change, rebuild ...
#   bash scripts/golden.sh [PRTBAKE] | diff before.txt -
# The commands: the demo job file; env (orders, windows, quantities, auto order, yaw,
# GAMES202); rotate (exact, projection); transport in all three modes with its glTF and
# GAMES202 copies; glossy matrices with CPCA and prtbake cpca; lut variants; prefilter
# (GGX, Charlie, Lambertian; KTX2 and OpenEXR); ibl for every target; every preview; a
# job file run in two shards and merged. Data files are hashed as they are; a JSON file
# is hashed after removing what differs from run to run (timings, the device's name,
# dates, absolute paths: see CANON below), with its keys sorted. Runs with the CPU device
# unless PRTBAKE_DEVICE says otherwise; takes about a minute here.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PRTBAKE=$(realpath "${1:-$ROOT/build/prtbake}")
export PRTBAKE_DEVICE=${PRTBAKE_DEVICE:-cpu}
work=$(mktemp -d /tmp/prtbake-golden.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/in" "$work"/out/{env,rotate,transport,glossy,lut,prefilter,preview,shards}
cp "$ROOT"/assets/{sky.exr,scene.gltf,scene.bin,demo.json} "$work/in/"
cd "$work"
p() { "$PRTBAKE" "$@" --quiet >>"$work/log.txt" 2>&1 || { echo "golden: prtbake $* failed:" >&2; tail -5 "$work/log.txt" >&2; exit 1; }; }
o=out
# The demo job file (it writes to ../out/demo from in/).
p run in/demo.json
# env
p env in/sky.exr -o $o/env/radiance5.json --order 5 --window hann --games202 $o/env/light.txt
p env in/sky.exr -o $o/env/irradiance.json --order 3 --quantity irradiance --window auto
p env in/sky.exr -o $o/env/over_pi.json --order 4 --quantity irradiance_over_pi --window lanczos --yaw 30
p env in/sky.exr -o $o/env/auto.json --order auto --tolerance 0.05
# rotate
p rotate $o/env/radiance5.json -o $o/rotate/euler.json --euler-zyz 10,20,30
p rotate $o/env/radiance5.json -o $o/rotate/quat.json --quat 0.9,0.1,0.3,0.2 --method projection
# transport
p transport in/scene.gltf -o $o/transport/unshadowed.npy --mode unshadowed --order 3 --samples 64
p transport in/scene.gltf -o $o/transport/shadowed.npy --mode shadowed --order 4 --samples 64 --gltf $o/transport/shadowed.glb --games202 $o/transport/transport.txt
p transport in/scene.gltf -o $o/transport/inter.npy --mode interreflected --bounces 2 --order 3 --samples 64 --seed 7
# glossy
p transport in/scene.gltf -o $o/glossy/m.npy --transfer matrix --mode shadowed --order 3 --samples 64 --cpca 4,3
p transport in/scene.gltf -o $o/glossy/ggx.npy --transfer matrix --mode unshadowed --order-out 3 --order-in 4 --brdf ggx:0.4 --dtype float16
p cpca $o/glossy/m.npy -o $o/glossy/cpca.npz --clusters 3 --vectors 2 --weights int8
# lut
p lut -o $o/lut/ggx.exr --size 32 --samples 256
p lut -o $o/lut/multi.exr --size 32 --samples 256 --multiscatter --half
p lut -o $o/lut/cloth.exr --size 32 --samples 256 --cloth
p lut -o $o/lut/beckmann.exr --size 32 --samples 256 --ndf beckmann --visibility smith-separable --kulla-conty
# prefilter
p prefilter in/sky.exr -o $o/prefilter/ggx.ktx2 --exr $o/prefilter/ggx.exr --size 32 --levels 4
p prefilter in/sky.exr -o $o/prefilter/charlie.ktx2 --lobe charlie --schedule filament --size 32 --levels 3
p prefilter in/sky.exr -o $o/prefilter/lambertian.ktx2 --exr $o/prefilter/lambertian.exr --lobe lambertian --size 16 --levels 1 --float32
# ibl
p ibl in/sky.exr -o $o/ibl --target all --size 32 --skybox-size 32 --lut-size 32
# previews
p preview env in/sky.exr -o $o/preview/env.png --order 4 --size 128
p preview env $o/env/radiance5.json -o $o/preview/env_sh.png --size 128
p preview lut $o/lut/ggx.exr -o $o/preview/lut.png
p preview prefilter in/sky.exr -o $o/preview/prefilter.png --base 16 --size 128
p preview mesh in/scene.gltf --transport $o/transport/shadowed.npy --env $o/env/radiance5.json -o $o/preview/mesh.png --size 96x64
p preview mesh in/scene.gltf --matrices $o/glossy/m.npy --env $o/env/radiance5.json -o $o/preview/glossy.png --size 96x64 --lobe phong:20
p preview mesh in/scene.gltf --cpca $o/glossy/m.cpca.npz --env $o/env/radiance5.json -o $o/preview/cpca.png --size 96x64 --lobe ggx:0.5
# a job file run in two shards, then merged
cat > in/shards.json <<'JSON'
{"jobs": [
  {"id": "split-transport", "type": "transport", "input": "scene.gltf", "split": true,
   "outputs": {"npy": "../out/shards/transport.npy"}, "mode": "shadowed", "order": 3, "samples": 64},
  {"id": "env", "type": "env", "input": "sky.exr", "outputs": {"json": "../out/shards/env.json"}, "order": 3},
  {"id": "lut", "type": "lut", "outputs": {"exr": "../out/shards/lut.exr"}, "size": 16, "samples": 64}
]}
JSON
p run in/shards.json --shard 0/2
p run in/shards.json --shard 1/2
p merge in/shards.json --shards 2
# CANON: JSON without what changes from run to run.
cd "$work/out"
find . -type f | LC_ALL=C sort | WORK="$work" /usr/bin/python3 -c '
import hashlib, json, os, sys
# Keys whose values change from run to run: times, dates, the device, and the byte size of
# an output that holds them.
VOLATILE = ("timings", "seconds", "device", "utc", "date", "host", "pid", "bytes")
WORK = os.environ["WORK"] + "/"
def text(s):
    return s.replace(WORK, "")
def canon(v):
    if isinstance(v, dict):
        return {text(k): canon(x) for k, x in v.items() if not any(w in k.lower() for w in VOLATILE)}
    if isinstance(v, list):
        return [canon(x) for x in v]
    return text(v) if isinstance(v, str) else v
for path in (l.strip() for l in sys.stdin):
    data = open(path, "rb").read()
    if path.endswith(".json"):
        try:
            data = json.dumps(canon(json.loads(data)), sort_keys=True).encode()
        except ValueError:
            pass
    print(hashlib.sha256(data).hexdigest(), path[2:])
'
