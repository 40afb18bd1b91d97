#!/usr/bin/env bash
# Sets up prtbake (Debian packages + build) and runs the demo job file on the
# demo inputs in assets/ (a procedural sky with a sun and a small occluding
# scene, both made by build/prtbake_make_demo), then says where the results are.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [ ! -f assets/sky.exr ] || [ ! -f assets/scene.gltf ]; then
  ./build/prtbake_make_demo assets
fi
status=0
./build/prtbake run assets/demo.json "$@" || status=$?
echo
echo "Results in $(pwd)/out/demo:"
ls -l out/demo 2>/dev/null | sed 1d || true
exit $status
