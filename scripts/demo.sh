#!/usr/bin/env bash
# Sets up what the demo needs (the Debian packages of the library and the prtbake
# command, and a build of the command alone), runs the demo job file assets/demo.json
# on the demo inputs (a procedural sky with a sun and a small occluding scene, both made
# by prtbake_make_demo), renders preview images of what it baked, and lists the results.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
bash scripts/setup.sh --cli
if [ ! -f assets/sky.exr ] || [ ! -f assets/scene.gltf ]; then
  cmake --build build --target prtbake_make_demo
  ./build/prtbake_make_demo assets
fi
./build/prtbake run assets/demo.json "$@"
bash scripts/demo_previews.sh out/demo
out=$(pwd)/out/demo
cat <<TEXT

The demo baked, in $out ($(( $(date +%s) - start )) s in all):
  sky_radiance.json, sky_irradiance.json  SH of assets/sky.exr (radiance; irradiance, deringed)
  light.txt                               the same radiance SH as the GAMES202 viewer reads it
  scene_transport.npy, scene_prt.glb      PRT transport of assets/scene.gltf (2 bounces), as
                                          NumPy and as a glTF copy with _PRT_T* attributes
  brdf_lut.exr                            the split-sum BRDF table (R = A, G = B)
  filament_ibl/                           a Filament package of the sky (prtbake ibl):
                                          ibl.ktx, skybox.ktx, sh.txt, README.txt
  *.json sidecars and *.manifest.json     conventions, sample counts, errors, timings
Open these images to see it:
  $out/demo_env.png    the sky, its order-5 SH and irradiance/pi
  $out/demo_scene.png  the scene lit by its baked transport under the sky
  $out/demo_lut.png    the BRDF table
TEXT
