#!/usr/bin/env bash
# Renders the demo images (DIR/demo_*.png; DIR defaults to docs/images, the README's) from
# the demo inputs in assets/ and the products of `prtbake run assets/demo.json` in out/demo/:
#   demo_env.png    assets/sky.exr | its order-5 SH radiance (Hann window) | irradiance/pi
#   demo_scene.png  assets/scene.gltf shaded with scene_transport.npy under sky_radiance.json,
#                   the sky map behind it, seen from 50 deg toward -X (the sun to the right) and 12 deg above
#   demo_lut.png    brdf_lut.exr, A and B over N.V and roughness
# The exposures (in stops) suit the demo sky, whose sun dominates its mean radiance.
# usage: scripts/demo_previews.sh [DIR]   (PRTBAKE=path/to/prtbake to use another binary)
set -euo pipefail
cd "$(dirname "$0")/.."
prtbake="${PRTBAKE:-./build/prtbake}"
demo=out/demo
images=${1:-docs/images}
for f in "$demo/sky_radiance.json" "$demo/scene_transport.npy" "$demo/brdf_lut.exr"; do
  if [ ! -f "$f" ]; then
    echo "demo_previews: $f is missing: run '$prtbake run assets/demo.json' first" >&2
    exit 1
  fi
done
mkdir -p "$images"
"$prtbake" preview env assets/sky.exr --order 5 --window hann --size 320 --exposure -4.5 \
  -o "$images/demo_env.png"
"$prtbake" preview mesh assets/scene.gltf --transport "$demo/scene_transport.npy" \
  --env "$demo/sky_radiance.json" --background assets/sky.exr --view -50,12 --size 640x400 \
  --exposure -4 -o "$images/demo_scene.png"
"$prtbake" preview lut "$demo/brdf_lut.exr" --size 192 -o "$images/demo_lut.png"
