#!/usr/bin/env bash
# GPU portability without a GPU: compiles kernel variants with clang for NVIDIA's OpenCL
# target (nvptx64-nvidia-nvcl, OpenCL C 1.2), so that a construct only PoCL accepts
# fails here, and so that a helper called but never defined (a plain C99 `inline` that
# PoCL and NVIDIA's compiler happen to inline) fails too. Each LIST holds "file<TAB>options" lines: build/tests/kernel_variants
# prints every variant the host's option builders can produce, and PRTBAKE_BUILD_LOG
# (scripts/test.sh) records what the tests actually built. Every kernels/*.cl file must
# appear in some list.
#
# usage: scripts/nvptx_check.sh LIST...
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -gt 0 ] || { sed -n '2,9p' "$0"; exit 2; }
# clang-15 comes with PoCL (libpocl2 depends on it).
clang=$(command -v clang-15 || command -v clang || true)
[ -n "$clang" ] || { echo "nvptx check: clang not found (apt-get install clang-15)" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Variants of the files in kernels/ (a test's own kernel directory is not ours to check).
cat "$@" | sort -u | while IFS=$'\t' read -r file options; do
  [ -f "kernels/$file" ] && printf '%s\t%s\n' "$file" "$options"
done >"$work/variants" || true
status=0
# What NVIDIA's own compiler refuses and clang's nvptx target takes: __builtin_prefetch on a
# __global pointer (driver 580, bench/results/gpu.md). Only bvh_packet.clh's CPU-only
# BVH_PREFETCH may use it.
if grep -n '__builtin_prefetch' kernels/*.cl kernels/*.clh kernels/*.h | grep -v '#define BVH_PREFETCH(p) __builtin_prefetch(p)' |
  grep -v '^[^:]*:[0-9]*: *//'; then
  echo "nvptx check: __builtin_prefetch outside BVH_PREFETCH (NVIDIA's compiler refuses it on __global pointers)" >&2
  status=1
fi
# A plain `inline` definition has no body of its own (C99): where the compiler does not inline a
# call, a driver that links with clang finds it undefined (see compile below). Whether it inlines
# depends on the variant and the optimiser, so the source is checked too.
if grep -n '^inline ' kernels/*.cl kernels/*.clh kernels/*.h; then
  echo "nvptx check: a plain 'inline' helper (above); write 'static inline'" >&2
  status=1
fi
for f in kernels/*.cl; do
  if ! cut -f1 "$work/variants" | grep -qx "$(basename "$f")"; then
    echo "nvptx check: no variant of $(basename "$f") is listed, so it is not checked" >&2
    status=1
  fi
done
compile() {
  local file options n
  IFS=$'\t' read -r file options <<<"$1"
  n=$(printf '%s' "$1" | cksum | cut -d' ' -f1)
  # shellcheck disable=SC2086
  if ! "$clang" -target nvptx64-nvidia-nvcl -cl-std=CL1.2 -Xclang -finclude-default-header \
      -Werror=implicit-function-declaration -I kernels $options -S -o "$work/$n.ptx" "kernels/$file" \
      2>"$work/$n.err"; then
    { echo "nvptx check: $file with '$options' does not compile for nvptx64-nvidia-nvcl:"; sed 's/^/  /' "$work/$n.err"; } >&2
    return 1
  fi
  # A function of ours (OpenCL's builtins are the mangled _Z names) that the PTX declares but
  # never defines: a plain C99 `inline` definition that the compiler chose not to inline, which
  # a driver that links with clang (not PoCL, not NVIDIA's) cannot resolve. Helpers are
  # `static inline`.
  local undefined
  undefined=$(awk '/^\.func/ { s = $0; gsub(/\([^)]*\)/, "", s); n = split(s, w, " "); name = w[n]; sub(/\($/, "", name); next }
    name != "" && $0 == ";" { if (name !~ /^_Z/) declared[name] = 1; name = "" }
    name != "" && $0 == "{" { defined[name] = 1; name = "" }
    END { for (f in declared) if (!(f in defined)) print f }' "$work/$n.ptx" | sort | tr '\n' ' ')
  if [ -n "$undefined" ]; then
    echo "nvptx check: $file with '$options' calls functions it never defines: $undefined(make them static inline)" >&2
    return 1
  fi
  rm -f "$work/$n.ptx" "$work/$n.err"
}
export -f compile
export clang work
count=$(wc -l <"$work/variants")
failed=0
xargs -d '\n' -P "$(nproc)" -n 1 bash -c 'compile "$1"' _ <"$work/variants" || failed=1
if [ "$failed" -ne 0 ]; then
  echo "nvptx check: FAILED (of $count kernel variants)" >&2
  exit 1
fi
echo "nvptx check: all $count kernel variants compile for nvptx64-nvidia-nvcl (OpenCL C 1.2)"
exit $status
