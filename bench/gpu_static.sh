#!/usr/bin/env bash
# What a GPU's compiler makes of each kernel variant, without a GPU: clang compiles the
# variant for NVIDIA's OpenCL target with libclc's builtins linked in (so that the PTX is
# whole), and NVIDIA's ptxas assembles it for an H100/H200 (sm_90) and reports each kernel's
# registers, stack frame (private arrays, in local memory) and spills. From the registers,
# the warps an SM can hold (65,536 registers in units of 256 a warp, at most 64 warps).
# NVIDIA's own OpenCL compiler optimises the source in its own way: read the figures as a
# proxy (bench/results/gpu.md compares them with the device's where a run had one).
#
# Needs clang-15, libclc-15 (apt-get install libclc-15) and ptxas (a CUDA toolkit; PTXAS or
# /usr/local/cuda/bin/ptxas).
#
# usage: bench/gpu_static.sh LIST [OUT.tsv]
#   LIST: "file<TAB>options" lines, as build/tests/kernel_variants prints them
#   prints one line per kernel and variant (tab-separated, with a header) to OUT.tsv or stdout
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { sed -n '2,15p' "$0"; exit 2; }
ptxas=${PTXAS:-/usr/local/cuda/bin/ptxas}
clc=/usr/lib/clc/nvptx64--nvidiacl.bc
command -v clang-15 >/dev/null || { echo "gpu_static: clang-15 not found" >&2; exit 1; }
[ -f "$clc" ] || { echo "gpu_static: $clc not found (apt-get install libclc-15)" >&2; exit 1; }
[ -x "$ptxas" ] || { echo "gpu_static: ptxas not found at $ptxas (set PTXAS)" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
one() {
  local file options n
  IFS=$'\t' read -r file options <<<"$1"
  n=$(printf '%s' "$1" | cksum | cut -d' ' -f1)
  # shellcheck disable=SC2086
  if ! clang-15 -target nvptx64--nvidiacl -cl-std=CL1.2 -O2 -Xclang -finclude-default-header \
      -Xclang -mlink-builtin-bitcode -Xclang "$clc" -I kernels $options -S -o "$work/$n.ptx" \
      "kernels/$file" 2>/dev/null; then
    # clang 15 cannot select some of libclc's math for nvptx (cos in lut.cl's precise
    # variants): no figures for those
    printf '%s\t%s\t-\tclang failed\t\t\t\t\n' "$file" "$options"
    return 0
  fi
  "$ptxas" -arch=sm_90 -v "$work/$n.ptx" -o /dev/null 2>&1 | awk -v f="$file" -v o="$options" '
    /Compiling entry function/ { e = $7; gsub(/\047/, "", e) }
    /bytes stack frame/ { st = $1; ss = $5; sl = $9 }
    /Used [0-9]+ registers/ {
      for (i = 1; i <= NF; ++i) if ($i == "registers,") r = $(i - 1)
      warps = int(65536 / (int((r * 32 + 255) / 256) * 256)); if (warps > 64) warps = 64
      printf "%s\t%s\t%s\t%d\t%d\t%d\t%d\t%d\n", f, o, e, r, st, ss, sl, warps }'
  rm -f "$work/$n.ptx"
}
export -f one
export work clc ptxas
{
  printf 'file\toptions\tkernel\tregisters\tstack bytes\tspill stores\tspill loads\twarps per SM\n'
  sort -u "$1" | xargs -d '\n' -P "$(nproc)" -n 1 bash -c 'one "$1"' _ | sort
} >"${2:-/dev/stdout}"
