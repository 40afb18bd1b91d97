#!/usr/bin/env bash
# The speed-against-accuracy study: builds what it needs, runs every sweep, writes
# bench/results/study/ (CSV, JSON), docs/images/accuracy_*.png and docs/accuracy.md.
#   bash bench/study/run.sh          full study (~9 min on the 2-core machine, plus the build)
#   STUDY_QUICK=1 bash bench/study/run.sh   smaller sweeps (a few minutes)
# Installs what it needs (the build's Debian packages and python3-matplotlib for the plots)
# as root or via sudo, like scripts/setup.sh.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
. "$ROOT/scripts/packages.sh"
# shellcheck disable=SC2086  # the list is split into packages on purpose
install_missing $PRTBAKE_PKGS python3-matplotlib
BUILD=${BUILD:-$ROOT/build}
OUT=$ROOT/bench/results/study
mkdir -p "$OUT" "$ROOT/docs/images"
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$BUILD/pocl-cache}
START=$(date +%s)

cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD" -j2 --target prtbake prtbake_cli bench_lut >/dev/null

# The study program links like the benchmarks: reuse bench_lut's compile and link lines.
FLAGS=$(sed -n 's/^CXX_FLAGS = //p' "$BUILD/bench/CMakeFiles/bench_lut.dir/flags.make")
DEFS=$(sed -n 's/^CXX_DEFINES = //p' "$BUILD/bench/CMakeFiles/bench_lut.dir/flags.make")
INCS=$(sed -n 's/^CXX_INCLUDES = //p' "$BUILD/bench/CMakeFiles/bench_lut.dir/flags.make")
LINK=$(cat "$BUILD/bench/CMakeFiles/bench_lut.dir/link.txt")
STUDY_BIN=$BUILD/bench/study_speed_accuracy
if [ ! -x "$STUDY_BIN" ] || [ "$ROOT/bench/study/study.cpp" -nt "$STUDY_BIN" ] || [ "$BUILD/libprtbake.a" -nt "$STUDY_BIN" ]; then
  eval "c++ $DEFS $INCS $FLAGS -c '$ROOT/bench/study/study.cpp' -o '$BUILD/bench/study.o'"
  # bench_lut's link line with its object and output swapped for ours.
  LINK=${LINK//CMakeFiles\/bench_lut.dir\/bench_lut.cpp.o/study.o}
  LINK=${LINK// -o bench_lut / -o study_speed_accuracy }
  (cd "$BUILD/bench" && eval "$LINK")
fi

QUICK=${STUDY_QUICK:+quick}
"$STUDY_BIN" "$OUT/study.csv" "$ROOT/assets/sky.exr" $QUICK 2> "$OUT/study.log"

# --order auto (irradiance, tolerance 1e-2) for the shared environment maps and the demo sky.
AUTO=$OUT/order_auto.csv
echo "map,chosen_order,achieved_error" > "$AUTO"
MAPS=("$ROOT/assets/sky.exr")
DATA=$ROOT/../shared/data/envmaps
[ -d "$DATA" ] || DATA=/work/shared/data/envmaps
if [ -d "$DATA" ]; then
  for d in "$DATA"/games202/*/ "$DATA"/hdr/* "$DATA"/openexr/*; do
    [ -e "$d" ] || continue
    case "$d" in *.txt|*.md|*LICENSE*) continue;; esac
    MAPS+=("${d%/}")
  done
fi
for m in "${MAPS[@]}"; do
  tmp=$(mktemp -d)
  if "$BUILD/prtbake" env "$m" -o "$tmp/sh.json" --order auto --tolerance 1e-2 --quantity irradiance --quiet \
       2> "$tmp/err.txt"; then
    python3 - "$m" "$tmp/sh.json" "$ROOT" >> "$AUTO" <<'PY'
import json, sys, os
j = json.load(open(sys.argv[2]))
def find(o, key):
    if isinstance(o, dict):
        if key in o: return o[key]
        for v in o.values():
            r = find(v, key)
            if r is not None: return r
    return None
a = find(j, "order_selection") or {}
order = a.get("chosen_order")
err = a.get("achieved_error")
print(f"{os.path.relpath(sys.argv[1], sys.argv[3])},{order},{err}")
PY
  else
    echo "$(basename "$m"),failed,$(head -c 200 "$tmp/err.txt" | tr ',\n' '; ')" >> "$AUTO"
  fi
  rm -rf "$tmp"
done

# The first python3 that imports module $1 (empty when none does).
python_with() {
  for p in python3 /usr/bin/python3; do
    if command -v "$p" >/dev/null && "$p" -c "import $1" 2>/dev/null; then echo "$p"; return; fi
  done
}

END=$(date +%s)
echo "{\"runtime_s\": $((END - START)), \"quick\": \"${QUICK:-no}\"}" > "$OUT/run.json"
# The report needs matplotlib for its plots.
PY=$(python_with matplotlib)
PY=${PY:-python3}
"$PY" "$ROOT/bench/study/make_report.py" "$ROOT"
echo "study: $((END - START)) s; results in $OUT, report in docs/accuracy.md"
