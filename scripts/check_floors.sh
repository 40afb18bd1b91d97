#!/usr/bin/env bash
# The library's floors (docs/architecture.md): every quoted #include of host/src and
# host/include/prtbake, of service/ and of python/, read as an edge between folders, must point to the
# same floor or a lower one, and the folders' graph must have no cycle. Prints each
# offending include; exit 1 when there is one.
#   floor 0 core      1 io      2 geometry      3 env lut prefilter transport glossy
#   floor 4 ibl preview probes      5 service      6 python (the Python module)
set -euo pipefail
cd "$(dirname "$0")/.."
# The public headers' folders (host/include/prtbake/NAME.h).
public_folder() {
  case "$1" in
    atomic_file|clock|progress|error|hash|limits|raw_vector|runtime|sh|sh_rotate|tolerance|envmap) echo core ;;
    exr) echo io ;;
    mesh|bvh) echo geometry ;;
    env|env_sh) echo env ;;
    engine|ibl) echo ibl ;;
    lut|prefilter|transport|glossy|preview|probes|lightmap) echo "$1" ;;
    *) echo "?" ;;
  esac
}
floor() {
  case "$1" in
    core) echo 0 ;; io) echo 1 ;; geometry) echo 2 ;;
    env|lut|prefilter|transport|glossy) echo 3 ;;
    ibl|preview|probes|lightmap) echo 4 ;; service) echo 5 ;; python) echo 6 ;; kernels) echo 0 ;;
    *) echo 99 ;;
  esac
}
folder_of_file() {  # a source file's folder
  case "$1" in
    host/src/*/*) f=${1#host/src/}; echo "${f%%/*}" ;;
    host/include/prtbake/*) n=$(basename "$1" .h); public_folder "$n" ;;
    service/*) echo service ;;
    python/*) echo python ;;
    *) echo "?" ;;
  esac
}
folder_of_include() {  # a quoted include's folder, or "" for one outside the library
  case "$1" in
    prtbake/*) public_folder "$(basename "$1" .h)" ;;
    core/*|io/*|geometry/*|env/*|lut/*|prefilter/*|transport/*|glossy/*|preview/*|ibl/*|probes/*|lightmap/*) echo "${1%%/*}" ;;
    *.clh|bvh_types.h) echo kernels ;;
    *) echo "" ;;
  esac
}
bad=0
edges=$(mktemp)
trap 'rm -f "$edges"' EXIT
while IFS= read -r file; do
  from=$(folder_of_file "$file")
  if [ "$from" = "?" ]; then echo "floors: $file: not in a known folder" >&2; bad=1; continue; fi
  while IFS= read -r inc; do
    to=$(folder_of_include "$inc")
    [ -n "$to" ] || continue
    if [ "$to" = "?" ]; then echo "floors: $file: #include \"$inc\": a header of no known folder" >&2; bad=1; continue; fi
    if [ "$(floor "$to")" -gt "$(floor "$from")" ]; then
      echo "floors: $file ($from, floor $(floor "$from")) includes \"$inc\" ($to, floor $(floor "$to"))" >&2
      bad=1
    fi
    [ "$to" = "$from" ] || [ "$to" = kernels ] || echo "$from $to" >>"$edges"
  done < <(sed -n 's/^#include "\([^"]*\)".*/\1/p' "$file")
done < <(find host/src host/include/prtbake service python -name '*.cpp' -o -name '*.h' | sort)
# No cycle among folders: tsort reports one.
if ! sort -u "$edges" | tsort >/dev/null 2>"$edges.err"; then
  echo "floors: the folders include each other in a cycle:" >&2
  cat "$edges.err" >&2
  bad=1
fi
rm -f "$edges.err"
[ "$bad" = 0 ] && echo "floors: $(sort -u "$edges" | wc -l) edges between folders, all downward or level, no cycle"
exit "$bad"
