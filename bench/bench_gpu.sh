#!/usr/bin/env bash
# prtbake on a machine with an NVIDIA GPU beside PoCL's CPU device, in one run of about six
# minutes: what enumerated (prtbake devices, nvidia-smi, clinfo), the torus knot's transport
# (shadowed 1024 / 8192 / 65536 rays per vertex, 1024 also in work-groups of 32, 128 and 256
# instead of the GPU's 64, interreflected with one bounce; occlusion rays per second from the
# sidecar's kernel time; GPU coefficients against the CPU's; bench_transport's knot with the
# scalar kernels at 1, 8 and 32 work-items per vertex),
# cold and warm `prtbake lut` (empty NVIDIA and PoCL program caches), whole commands (env,
# lut, prefilter, ibl, glossy transfer with CPCA, mesh transport and preview, a probe grid) on both
# devices, the registers, stack and spills of every kernel variant the GPU built (NVIDIA's
# -cl-nv-verbose, through bench_kernels), and the benchmark programs of build/bench on both. Every step runs under
# `timeout` and within an overall budget (a step that hangs is recorded as TIMEOUT, one that
# the budget no longer allows as SKIPPED); a failing step is recorded with its error line and
# the run goes on. Writes RESULTS/gpu.md (the report, rewritten after every step),
# RESULTS/gpu_log.txt (every command and its output) and RESULTS/lut_gpu.json (bench_lut).
#
#   bash bench/bench_gpu.sh RESULTS
#   QUICK=1 bash bench/bench_gpu.sh RESULTS      small sample counts and meshes (a check of the script)
#   BUDGET=S (default 330): seconds after which no further step starts; each step's limit is
#   cut to what is left of it. BENCH_GPU_DEVICE=N: the device index used as "the GPU".
#
# Runs prebuilt binaries: the machine needs none of the build's packages. Before, on the
# build machine, `bash bench/gpu_pack.sh` fills .gpu/ (git-ignored) with what is carried:
#   .gpu/bin/      prtbake, bench_env, bench_glossy, bench_kernels, bench_lut, bench_prefilter,
#                  bench_preview, bench_transport (stripped)
#   .gpu/lib/      libOpenEXR-3_1.so.30, libIex-3_1.so.30, libIlmThread-3_1.so.30,
#                  libImath-3_1.so.29, libtinygltf.so.2d, libtinyobjloader.so.2rc10, libstb.so.0,
#                  libz.so.1 (LD_LIBRARY_PATH=.gpu/lib)
#   .gpu/lib-cxx/  libstdc++.so.6, libgcc_s.so.1: added only when the machine's libstdc++ lacks
#                  a version the binaries need (GLIBCXX_3.4.29); glibc 2.34 or newer is needed
#   .gpu/lib-ocl/  ocl-icd's libOpenCL.so.1: added only when ldconfig knows no libOpenCL.so.1
#                  (the machine's own loader reads its ICDs in /etc/OpenCL/vendors)
#   .gpu/data/     mary.obj, venice_sunset_1k.hdr, games202/Skybox2048, knot.obj.gz
#   .gpu/paths.env the CLI and data paths compiled into the benchmarks: made to exist (as
#                  links to .gpu/bin/prtbake and .gpu/data) for the run when they do not
# The OpenCL ICDs (NVIDIA's, PoCL) are the machine's own.
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
[ $# -ge 1 ] || { echo "usage: bash bench/bench_gpu.sh RESULTS_DIR" >&2; exit 2; }
mkdir -p "$1" && RES=$(cd "$1" && pwd)
G=${PRTBAKE_GPU_PACK:-$ROOT/.gpu}
BIN=$G/bin
DATA=$G/data
PRTBAKE=$BIN/prtbake
QUICK=${QUICK:-0}
BUDGET=${BUDGET:-330}
REPORT=$RES/gpu.md
LOG=$RES/gpu_log.txt
work=$(mktemp -d "${TMPDIR:-/tmp}/prtbake-gpu.XXXXXX")
created=()  # links and folders this run made outside $work, removed at the end
cleanup() {
  local i
  for ((i = ${#created[@]} - 1; i >= 0; --i)); do
    if [ -L "${created[i]}" ]; then rm -f "${created[i]}"; else rmdir "${created[i]}" 2>/dev/null; fi
  done
  rm -rf "$work"
}
trap cleanup EXIT
: > "$LOG"
log() { printf '%s\n' "$*" >> "$LOG"; }

if [ "$QUICK" = 1 ]; then
  S1=64 S2=256 S3=1024 SIR=32 RUNS_COLD=2
  BT=(--repeats 1 --samples-large 16) BP=(--repeats 1 --triangles 20000) BG=(--repeats 1 --triangles 4000) PF_RUNS=1
  GLOSSY=(--order 3 --samples 64 --cpca 8,4) IBL=(--target threejs,filament,babylon --size 64 --skybox-size 64)
else
  S1=1024 S2=8192 S3=65536 SIR=1024 RUNS_COLD=3
  BT=(--repeats 3) BP=(--repeats 3) BG=(--repeats 1) PF_RUNS=3
  GLOSSY=(--order 5 --samples 1024 --cpca 32,8) IBL=()
fi

# --- report pieces: $work/head.md, section files $work/sec_NN.md, steps in $work/steps.tsv ---
: > "$work/steps.tsv"
sec() { printf '%s\n' "$@" >> "$work/sec_$CUR.md"; }  # append lines to the current section
render() {
  {
    cat "$work/head.md" 2>/dev/null
    for f in "$work"/sec_*.md; do [ -f "$f" ] && { cat "$f"; echo; }; done
    echo "## Steps"
    echo
    echo "Elapsed $SECONDS s of the ${BUDGET} s budget when this was written."
    echo
    echo "| step | device | status | wall [s] | limit [s] |"
    echo "|---|---|---|---|---|"
    awk -F'\t' '{printf "| %s | %s | %s | %s | %s |\n", $2, $3, $4, $5, $6}' "$work/steps.tsv"
    echo
    echo "## Failures"
    echo
    if awk -F'\t' '$4 != "OK" && $4 != "SKIPPED" {n++} END {exit n ? 0 : 1}' "$work/steps.tsv"; then
      awk -F'\t' '$4 != "OK" && $4 != "SKIPPED" {printf "- %s (%s): %s: `%s`\n", $2, $3, $4, $7}' "$work/steps.tsv"
    else
      echo "None."
    fi
    awk -F'\t' '$4 == "SKIPPED" {n++} END {if (n) printf "\n%d steps skipped: the budget was spent.\n", n}' "$work/steps.tsv"
  } > "$REPORT.tmp" && mv "$REPORT.tmp" "$REPORT"
}

# step ID LABEL DEVICE LIMIT CMD...: runs CMD under timeout (limit cut to the budget left),
# its output in $work/ID.out and the log; records status, wall time and error line.
STATUS= WALL=
step() {
  local id=$1 label=$2 dev=$3 lim=$4; shift 4
  local left=$((BUDGET - SECONDS)) out=$work/$id.out rc t0 t1 err
  if [ "$left" -lt 8 ]; then
    STATUS=SKIPPED WALL=-
    log "=== [$id] $label ($dev): SKIPPED, ${left} s of the budget left"
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$id" "$label" "$dev" SKIPPED - "$lim" "budget spent" >> "$work/steps.tsv"
    : > "$out"
    render
    return 1
  fi
  [ "$lim" -gt "$left" ] && lim=$left
  log "=== [$id] $label ($dev), limit ${lim} s, at ${SECONDS} s: $(printf '%q ' "$@")"
  t0=$(date +%s.%N)
  # The GPU's steps log the kernel variants they build (section 4b builds them again, verbosely).
  if [ "$dev" = gpu ]; then
    timeout -k 5 "$lim" env PRTBAKE_BUILD_LOG="$work/built_gpu.tsv" "$@" > "$out" 2>&1 < /dev/null
  else
    timeout -k 5 "$lim" "$@" > "$out" 2>&1 < /dev/null
  fi
  rc=$?
  t1=$(date +%s.%N)
  WALL=$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.2f", b - a}')
  if [ "$(wc -c < "$out")" -gt 200000 ]; then
    { head -c 50000 "$out"; echo "[... cut ...]"; tail -c 100000 "$out"; } >> "$LOG"
  else
    cat "$out" >> "$LOG"
  fi
  err=
  if [ "$rc" -eq 124 ] || { [ "$rc" -eq 137 ] && awk -v w="$WALL" -v l="$lim" 'BEGIN {exit !(w >= l)}'; }; then
    STATUS=TIMEOUT err="no result within ${lim} s"
  elif [ "$rc" -ne 0 ]; then
    STATUS="FAIL ($rc)"
    err=$(errline "$out")
  else
    STATUS=OK
  fi
  log "=== [$id] $STATUS, rc $rc, wall $WALL s"
  err=$(printf '%s' "$err" | tr '\t|`' '  ' | cut -c1-300)
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$id" "$label" "$dev" "$STATUS" "$WALL" "$lim" "$err" >> "$work/steps.tsv"
  render
  [ "$STATUS" = OK ]
}
# Output of a step in the report: the last N lines (default 40) in a code block.
show() {
  local id=$1 n=${2:-40}
  sec '```'
  if [ -s "$work/$id.out" ]; then tail -n "$n" "$work/$id.out" | cut -c1-400 >> "$work/sec_$CUR.md"; else sec '(no output)'; fi
  sec '```'
}
# The line of FILE that best says what went wrong.
errline() {
  local pat
  for pat in 'error:' 'what\(\)' 'Error|ERROR|failed|not found|cannot|Abort|Segmentation|Killed'; do
    grep -m1 -E "$pat" "$1" 2>/dev/null && return 0
  done
  grep -v '^[[:space:]]*$' "$1" 2>/dev/null | tail -n 1
}
# amend ID FILE: FILE (a child's own log) into the step's output and its error line.
amend() {
  local out=$work/$1.out e
  [ -s "$2" ] || return 0
  { echo "--- $2:"; tail -n 20 "$2"; } | tee -a "$out" >> "$LOG"
  sec "Its command's own log, $(basename "$2"):" '```'
  tail -n 20 "$2" | cut -c1-400 >> "$work/sec_$CUR.md"
  sec '```' ""
  e=$(errline "$2" | tr '\t|`' '  ' | cut -c1-300)
  [ -n "$e" ] && awk -F'\t' -v OFS='\t' -v id="$1" -v e="$e" '$1 == id {$7 = e} {print}' "$work/steps.tsv" > "$work/steps.tmp" &&
    mv "$work/steps.tmp" "$work/steps.tsv"
  render
}
have() { command -v "$1" > /dev/null 2>&1; }
# jnum FILE BLOCK KEY: a number from a JSON sidecar, KEY inside the object BLOCK ("" for anywhere).
jnum() {
  if [ -n "$2" ]; then sed -n "/\"$2\": {/,/}/p" "$1"; else cat "$1"; fi 2>/dev/null |
    grep -o "\"$3\": *[-0-9.eE+]*" | head -n 1 | sed 's/.*: *//'
}

# --- libraries and paths ---
export LD_LIBRARY_PATH="$G/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
libnotes=()
LDCONFIG=$(command -v ldconfig || echo /sbin/ldconfig)
if ! "$LDCONFIG" -p 2>/dev/null | grep -q 'libOpenCL\.so\.1'; then
  LD_LIBRARY_PATH=$LD_LIBRARY_PATH:$G/lib-ocl
  libnotes+=("ldconfig knows no libOpenCL.so.1: ocl-icd's loader from .gpu/lib-ocl")
fi
probe=$("$PRTBAKE" --version 2>&1)
if printf '%s' "$probe" | grep -q 'GLIBCXX\|CXXABI\|libstdc++\|libgcc_s'; then
  LD_LIBRARY_PATH=$G/lib:$G/lib-cxx:${LD_LIBRARY_PATH#"$G/lib:"}
  libnotes+=("the machine's libstdc++ is too old ($(printf '%s' "$probe" | head -n 1)): .gpu/lib-cxx used")
  probe=$("$PRTBAKE" --version 2>&1)
fi
if printf '%s' "$probe" | grep -q 'libOpenCL'; then
  LD_LIBRARY_PATH=$LD_LIBRARY_PATH:$G/lib-ocl
  libnotes+=("libOpenCL.so.1 did not load ($(printf '%s' "$probe" | head -n 1)): .gpu/lib-ocl added")
  probe=$("$PRTBAKE" --version 2>&1)
fi
RUNS_AT_ALL=1
printf '%s' "$probe" | grep -q '^prtbake ' || { RUNS_AT_ALL=0; libnotes+=("**prtbake does not start**: $(printf '%s' "$probe" | head -n 2 | tr '\n' ' ')"); }
PRTBAKE_CLI_PATH= PRTBAKE_BENCH_DATA_DIR= PACKED_FROM=
[ -f "$G/paths.env" ] && . "$G/paths.env"
pathnotes=()
link_if_absent() {  # TARGET LINK: make LINK (and its missing parents) point at TARGET for this run
  local target=$1 link=$2 d missing=()
  [ -n "$link" ] || return 0
  if [ -e "$link" ]; then pathnotes+=("$link exists: used as it is"); return 0; fi
  d=$(dirname "$link")
  while [ ! -e "$d" ]; do missing=("$d" "${missing[@]}"); d=$(dirname "$d"); done
  if mkdir -p "$(dirname "$link")" 2>/dev/null && ln -s "$target" "$link" 2>/dev/null; then
    created+=("${missing[@]}" "$link")
    pathnotes+=("$link -> $target (made for this run)")
  else
    pathnotes+=("$link is absent and could not be made: the benchmarks that use it fail")
  fi
}
link_if_absent "$PRTBAKE" "$PRTBAKE_CLI_PATH"
link_if_absent "$DATA" "$PRTBAKE_BENCH_DATA_DIR"
export CUDA_CACHE_PATH=$work/cuda-cache POCL_CACHE_DIR=$work/pocl-cache
mkdir -p "$CUDA_CACHE_PATH" "$POCL_CACHE_DIR"
unset PRTBAKE_DEVICE CUDA_CACHE_DISABLE

# --- 1. the machine and its devices ---
devs=$("$PRTBAKE" devices 2>&1)
GPU=$(printf '%s\n' "$devs" | sed 's/^\*/ /' | awk '$2 == "gpu" && /\[NVIDIA CUDA\]/ {print $1; exit}')
[ -n "$GPU" ] || GPU=$(printf '%s\n' "$devs" | sed 's/^\*/ /' | awk '$2 == "gpu" && /NVIDIA/ {print $1; exit}')
[ -n "$GPU" ] || GPU=gpu
GPU=${BENCH_GPU_DEVICE:-$GPU}  # a check of the script on a machine without a GPU: BENCH_GPU_DEVICE=0
CPU=$(printf '%s\n' "$devs" | sed 's/^\*/ /' | awk '$2 == "cpu" && /Portable Computing Language/ {print $1; exit}')
[ -n "$CPU" ] || CPU=cpu
{
  echo "# prtbake on the GPU machine (bench/bench_gpu.sh)"
  echo
  echo "$(date -u '+%Y-%m-%d %H:%M UTC'), $(hostname), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), $(awk '/MemTotal/ {printf "%.0f GiB", $2 / 1048576}' /proc/meminfo), $(uname -r); $( [ -r /etc/os-release ] && . /etc/os-release && echo "$PRETTY_NAME")."
  echo "Binaries packed from commit ${PACKED_FROM:-?}; QUICK=$QUICK; budget $BUDGET s; prtbake --device $GPU for the GPU, --device $CPU for the CPU (from the list below)."
  echo "Tools: python3 $(have python3 && echo yes || echo no), numpy $(python3 -c 'import numpy' 2>/dev/null && echo yes || echo no), /usr/bin/time $([ -x /usr/bin/time ] && echo yes || echo no), clinfo $(have clinfo && echo yes || echo no), nvidia-smi $(have nvidia-smi && echo yes || echo no)."
  echo
  echo "## Devices"
  echo
  echo '`prtbake devices`:'
  echo
  echo '```'
  printf '%s\n' "$devs"
  echo '```'
  echo
  echo "Libraries: LD_LIBRARY_PATH=$LD_LIBRARY_PATH; libOpenCL.so.1 => $(ldd "$PRTBAKE" 2>/dev/null | awk '$1 == "libOpenCL.so.1" {print $3}'), libstdc++.so.6 => $(ldd "$PRTBAKE" 2>/dev/null | awk '$1 == "libstdc++.so.6" {print $3}')."
  for n in "${libnotes[@]}" "${pathnotes[@]}"; do echo "- $n"; done
  echo
  echo "OpenCL ICDs (/etc/OpenCL/vendors): $(for f in /etc/OpenCL/vendors/*.icd; do [ -f "$f" ] && printf '%s: %s; ' "$(basename "$f")" "$(head -c 200 "$f" | tr '\n' ' ')"; done)"
  echo
  if have nvidia-smi; then
    echo '`nvidia-smi`:'
    echo
    echo '```'
    timeout 20 nvidia-smi --query-gpu=name,driver_version,memory.total,persistence_mode,clocks.max.sm,power.limit --format=csv 2>&1
    timeout 20 nvidia-smi 2>&1 | head -n 25
    echo '```'
  else
    echo "nvidia-smi: not found."
  fi
  echo
  if have clinfo; then
    echo '`clinfo -l`:'
    echo
    echo '```'
    timeout 30 clinfo -l 2>&1 | head -n 20
    echo '```'
  else
    echo "clinfo: not found."
  fi
  echo
} > "$work/head.md"
cat "$work/head.md" >> "$LOG"
render
step devices_gpu "prtbake devices (process start with the GPU platform)" gpu 30 "$PRTBAKE" devices --device "$GPU"
step devices_gpu2 "prtbake devices, again" gpu 30 "$PRTBAKE" devices --device "$GPU"

# --- 2. transport on the torus knot ---
CUR=10
sec "## Transport: the torus knot (102,400 vertices, 204,800 triangles), order 3" ""
KNOT=$work/knot.obj
if [ -f "$DATA/knot.obj.gz" ]; then gzip -dc "$DATA/knot.obj.gz" > "$KNOT"; fi
trow=()
knot() {  # ID LABEL DEVNAME DEV LIMIT ARGS...: one knot transport, its sidecar figures kept for the table
  # (GS=N before it: the kernels' work-group size, PRTBAKE_GROUP_SIZE, instead of the device's)
  local id=$1 label=$2 dn=$3 dev=$4 lim=$5; shift 5
  step "$id" "knot: $label" "$dn" "$lim" env ${GS:+PRTBAKE_GROUP_SIZE=$GS} "$PRTBAKE" transport "$KNOT" -o "$work/$id.npy" --device "$dev" "$@"
  trow+=("$id|$label|$dn|$STATUS|$WALL")
}
if [ -s "$KNOT" ]; then
  knot k_gpu_first "shadowed, 64 rays/vertex, first GPU transport (program build)" gpu "$GPU" 90 --samples 64
  knot k_cpu_first "shadowed, 64 rays/vertex, first CPU transport (program build)" cpu "$CPU" 90 --samples 64
  knot k_gpu_s1 "shadowed, $S1 rays/vertex" gpu "$GPU" 60 --samples "$S1"
  knot k_gpu_s1b "shadowed, $S1 rays/vertex, again" gpu "$GPU" 60 --samples "$S1"
  for gs in 32 128 256; do  # the device's default is 64 (Runtime::loopGroupSize), 32 work-items to a vertex
    GS=$gs knot "k_gpu_s1_g$gs" "shadowed, $S1 rays/vertex, work-groups of $gs" gpu "$GPU" 60 --samples "$S1"
  done
  knot k_cpu_s1 "shadowed, $S1 rays/vertex" cpu "$CPU" 60 --samples "$S1"
  knot k_gpu_s2 "shadowed, $S2 rays/vertex" gpu "$GPU" 60 --samples "$S2"
  knot k_cpu_s2 "shadowed, $S2 rays/vertex" cpu "$CPU" 60 --samples "$S2"
  knot k_gpu_s3 "shadowed, $S3 rays/vertex" gpu "$GPU" 45 --samples "$S3"
  knot k_gpu_ir "interreflected, 1 bounce, $SIR rays/vertex" gpu "$GPU" 60 --samples "$SIR" --mode interreflected --bounces 1 --bounce-tolerance 0
  knot k_cpu_ir "interreflected, 1 bounce, $SIR rays/vertex" cpu "$CPU" 60 --samples "$SIR" --mode interreflected --bounces 1 --bounce-tolerance 0
  sec "Whole commands (\`prtbake transport knot.obj -o T.npy --device D --samples N [--mode interreflected --bounces 1 --bounce-tolerance 0]\`); BVH, kernel and in-process times from each sidecar's \`timings_s\`; V×S: vertices × samples per vertex (the sidecar's \`samples.total\`), traced: the rays actually traced (\`samples.rays\`: unoccludable vertices take a closed form). The goal: 4 G occlusion rays/s on the GPU, V×S over the kernel time." ""
  sec "| run | device | status | wall [s] | BVH [s] | kernels [s] | in-process [s] | V×S | traced | G rays/s (V×S / kernels) | G rays/s (traced / kernels) | G rays/s (V×S / wall) |"
  sec "|---|---|---|---|---|---|---|---|---|---|---|---|"
  best=
  for r in "${trow[@]}"; do
    IFS='|' read -r id label dn st wall <<< "$r"
    j=$work/$id.json
    if [ "$st" = OK ] && [ -f "$j" ]; then
      bvh=$(jnum "$j" timings_s bvh) ker=$(jnum "$j" timings_s kernels) tot=$(jnum "$j" timings_s total)
      vs=$(jnum "$j" samples total) rays=$(jnum "$j" samples rays)
      line=$(awk -v l="$label" -v d="$dn" -v w="$wall" -v b="$bvh" -v k="$ker" -v t="$tot" -v v="$vs" -v r="$rays" 'BEGIN {
        printf "| %s | %s | OK | %s | %.3f | %.3f | %.3f | %.4g | %.4g | %.3f | %.3f | %.3f |", l, d, w, b, k, t, v, r,
          (k > 0 ? v / k * 1e-9 : 0), (k > 0 ? r / k * 1e-9 : 0), (w > 0 ? v / w * 1e-9 : 0) }')
      sec "$line"
      case $id in k_gpu_s2|k_gpu_s3) best="$best$(awk -v l="$label" -v v="$vs" -v k="$ker" 'BEGIN {g = k > 0 ? v / k * 1e-9 : 0; printf "%s: %.2f G rays/s (%s); ", l, g, (g >= 4 ? "goal met" : "below the goal")}')" ;; esac
    else
      sec "| $label | $dn | $st | $wall | | | | | | | | |"
    fi
  done
  sec "" "GPU against the 4 G rays/s goal: ${best:-no GPU figure.}" ""
  if have python3; then
    cmp_lines=$(timeout 60 python3 - "$work" <<'PY'
import os, struct, sys
w = sys.argv[1]
def load(path):
    b = open(path, 'rb').read()
    major = b[6]
    n, off = (struct.unpack('<H', b[8:10])[0], 10) if major == 1 else (struct.unpack('<I', b[8:12])[0], 12)
    header = b[off:off + n].decode()
    shape = tuple(int(x) for x in header.split('(')[1].split(')')[0].split(',') if x.strip())
    kind = 'e' if "'<f2'" in header else 'f'
    data = b[off + n:]
    return shape, struct.unpack('<%d%s' % (len(data) // struct.calcsize(kind), kind), data)
for a, c, what in [('k_gpu_s1', 'k_cpu_s1', 'shadowed'), ('k_gpu_s2', 'k_cpu_s2', 'shadowed'), ('k_gpu_ir', 'k_cpu_ir', 'interreflected'),
                   ('k_gpu_s1', 'k_gpu_s1b', 'GPU rerun')]:
    pa, pc = os.path.join(w, a + '.npy'), os.path.join(w, c + '.npy')
    if not (os.path.exists(pa) and os.path.exists(pc)):
        print('- %s against %s: an output is missing' % (a, c)); continue
    sa, x = load(pa); sc, y = load(pc)
    if sa != sc: print('- %s against %s: shapes differ %s %s' % (a, c, sa, sc)); continue
    stride = len(x) // sa[0]
    d0 = [abs(x[i] - y[i]) for i in range(0, len(x), stride)]
    da = [abs(p - q) for p, q in zip(x, y)]
    print('- %s (%s) against %s: shape %s; mean |dT00| %.3e, max |dT00| %.3e; mean |dT| over all coefficients %.3e, max %.3e; identical: %s'
          % (a, what, c, sa, sum(d0) / len(d0), max(d0), sum(da) / len(da), max(da), 'yes' if x == y else 'no'))
PY
    )
    sec "GPU coefficients against the CPU device's (same rays: same sampler and seed):" "" "$cmp_lines"
  else
    sec "No python3 here: the coefficients were not compared."
  fi
else
  sec "knot.obj.gz is not in $DATA: the knot was not measured."
fi
render

# --- 3. cold start of prtbake lut ---
CUR=20
sec "## Cold start: \`prtbake lut\` (defaults: 128², 1024 samples)" ""
sec "Cold: a new, empty CUDA_CACHE_PATH (NVIDIA's compute cache) or POCL_CACHE_DIR for the run; warm: the same cache again. Whole commands." ""
sec "| run | device | cache | status | wall [s] |" "|---|---|---|---|---|"
for i in $(seq "$RUNS_COLD"); do
  mkdir -p "$work/cold-cuda-$i"
  step "cold_gpu_$i" "lut, cold GPU #$i" gpu 60 env CUDA_CACHE_PATH="$work/cold-cuda-$i" "$PRTBAKE" lut -o "$work/lut_cold.exr" --device "$GPU"
  sec "| lut #$i | gpu | cold | $STATUS | $WALL |"
done
for i in $(seq "$RUNS_COLD"); do
  step "warm_gpu_$i" "lut, warm GPU #$i" gpu 60 env CUDA_CACHE_PATH="$work/cold-cuda-$RUNS_COLD" "$PRTBAKE" lut -o "$work/lut_warm.exr" --device "$GPU"
  sec "| lut #$i | gpu | warm | $STATUS | $WALL |"
done
step cold_gpu_nocache "lut, GPU, CUDA_CACHE_DISABLE=1" gpu 60 env CUDA_CACHE_DISABLE=1 "$PRTBAKE" lut -o "$work/lut_nc.exr" --device "$GPU"
sec "| lut | gpu | CUDA_CACHE_DISABLE=1 | $STATUS | $WALL |"
mkdir -p "$work/cold-pocl"
step cold_cpu "lut, cold CPU" cpu 60 env POCL_CACHE_DIR="$work/cold-pocl" "$PRTBAKE" lut -o "$work/lut_cold.exr" --device "$CPU"
sec "| lut | cpu | cold | $STATUS | $WALL |"
step warm_cpu "lut, warm CPU" cpu 60 env POCL_CACHE_DIR="$work/cold-pocl" "$PRTBAKE" lut -o "$work/lut_warm.exr" --device "$CPU"
sec "| lut | cpu | warm | $STATUS | $WALL |"
if [ -f "$work/lut_warm.json" ]; then sec "" "In-process timings of the last run (sidecar): $(sed -n '/"timings"/,/}/p' "$work/lut_warm.json" | tr -d '\n ' | cut -c1-200)"; fi
render

# --- 4. whole commands on both devices ---
CUR=30
MARY=$DATA/meshes/obj/mary.obj HDR=$DATA/envmaps/hdr/venice_sunset_1k.hdr SKY=$DATA/envmaps/games202/Skybox2048
sec "## Whole commands, GPU beside CPU" ""
sec "Inputs: venice_sunset_1k.hdr (1024×512 Radiance), games202/Skybox2048 (six 2048² JPEGs), mary.obj (7,905 vertices). Each command twice on each device (ibl once: its glTF target's LUT, 1e-4 tolerance with the cloth table, is the longest work here, ~55 s on 2 CPU cores): first (its programs built unless an earlier step built them; the caches of this run start empty) and warm." ""
sec "| command | GPU first [s] | GPU warm [s] | CPU first [s] | CPU warm [s] |" "|---|---|---|---|---|"
cell() { if [ "$STATUS" = OK ]; then printf '%s' "$WALL"; else printf '%s' "$STATUS"; fi; }
cli() {  # NAME RUNS LIMIT ARGS... (@OUT@: the output stem): the command RUNS times (1 or 2) on the GPU, then on the CPU
  local name=$1 runs=$2 lim=$3 a dn dev run row=""; shift 3
  for dn in gpu cpu; do
    dev=$GPU; [ $dn = cpu ] && dev=$CPU
    for run in first warm; do
      if [ $run = warm ] && [ "$runs" -lt 2 ]; then row="$row | -"; continue; fi
      a=("${@//@OUT@/$work/c_${name}_$dn}")
      step "c_${name}_${dn}_$run" "$name ($run)" $dn "$lim" "$PRTBAKE" "${a[@]}" --device "$dev"
      row="$row | $(cell)"
    done
  done
  sec "| \`prtbake $(printf '%s ' "$@" | sed "s|$DATA/||g; s|@OUT@|OUT|g")\`$row |"
}
cli env_hdr 2 30 env "$HDR" -o @OUT@.json
cli env_sky 2 30 env "$SKY" -o @OUT@.json --order 8
cli lut128 2 30 lut -o @OUT@.exr --size 128
cli lut512 2 30 lut -o @OUT@.exr --size 512 --samples 4096
cli prefilter 2 30 prefilter "$HDR" -o @OUT@.ktx2
cli mary 2 30 transport "$MARY" -o @OUT@.npy
cli glossy 2 45 transport "$MARY" -o @OUT@.npy --transfer matrix "${GLOSSY[@]}"
cli ibl 1 45 ibl "$HDR" -o @OUT@ "${IBL[@]}"
cli probes 2 45 probes "$MARY" -o @OUT@ --resolution 16,8,16 --samples 4096 --bounces 0 --env "$HDR"
row=""
for dn in gpu cpu; do
  dev=$GPU; [ $dn = cpu ] && dev=$CPU
  for run in first warm; do
    step "c_preview_${dn}_$run" "preview mesh ($run)" $dn 60 "$PRTBAKE" preview mesh "$MARY" --transport "$work/c_mary_$dn.npy" --env "$work/c_env_hdr_$dn.json" -o "$work/c_preview_$dn.png" --device "$dev"
    row="$row | $(cell)"
  done
done
sec "| \`prtbake preview mesh meshes/obj/mary.obj --transport T.npy --env SH.json -o OUT.png\` (T and SH from the commands above)$row |" ""
if have python3; then
  sec "GPU outputs against the CPU's:" ""
  sec "$(timeout 60 python3 - "$work" <<'PY'
import json, os, struct, sys
w = sys.argv[1]
def load(path):
    b = open(path, 'rb').read()
    n, off = (struct.unpack('<H', b[8:10])[0], 10) if b[6] == 1 else (struct.unpack('<I', b[8:12])[0], 12)
    header = b[off:off + n].decode()
    shape = tuple(int(x) for x in header.split('(')[1].split(')')[0].split(',') if x.strip())
    kind = 'e' if "'<f2'" in header else 'f'
    data = b[off + n:]
    return shape, struct.unpack('<%d%s' % (len(data) // struct.calcsize(kind), kind), data)
def p(name): return os.path.join(w, name)
for env in ('env_hdr', 'env_sky'):
    a, c = p('c_%s_gpu.json' % env), p('c_%s_cpu.json' % env)
    if os.path.exists(a) and os.path.exists(c):
        x = [v for row in json.load(open(a))['coefficients'] for v in row]
        y = [v for row in json.load(open(c))['coefficients'] for v in row]
        scale = max(abs(v) for v in y) or 1
        print('- %s: %d coefficients, max |GPU - CPU| %.3e (%.3e of the largest)' % (env, len(x), max(abs(s - t) for s, t in zip(x, y)), max(abs(s - t) for s, t in zip(x, y)) / scale))
    else:
        print('- %s: an output is missing' % env)
for npy, what in (('mary', 'mary.obj transport'), ('glossy', 'mary.obj transfer matrices')):
    a, c = p('c_%s_gpu.npy' % npy), p('c_%s_cpu.npy' % npy)
    if os.path.exists(a) and os.path.exists(c):
        sa, x = load(a); sc, y = load(c)
        if sa != sc: print('- %s: shapes differ %s %s' % (what, sa, sc)); continue
        stride = len(x) // sa[0]
        d0 = [abs(x[i] - y[i]) for i in range(0, len(x), stride)]
        step = max(1, len(x) // 2000000)
        da = [abs(x[i] - y[i]) for i in range(0, len(x), step)]
        print('- %s: shape %s; element 0 of each vertex: mean |GPU - CPU| %.3e, max %.3e; all elements%s: mean %.3e, max %.3e'
              % (what, sa, sum(d0) / len(d0), max(d0), '' if step == 1 else ' (every %dth)' % step, sum(da) / len(da), max(da)))
    else:
        print('- %s: an output is missing' % what)
PY
)"
else
  sec "No python3 here: the outputs were not compared."
fi
render

# --- 4b. what NVIDIA's compiler made of the kernels the GPU's steps built ---
CUR=35
sec "## Registers, stack and spills on the GPU (bench_kernels --extra -cl-nv-verbose)" ""
sec "Every kernel variant the GPU's steps above built, built again with NVIDIA's \`-cl-nv-verbose\` (ptxas's report in the build log); bench/gpu_static.sh gives the same figures from clang and ptxas without a GPU. Warps per SM: 65,536 registers in units of 256 a warp, at most 64." ""
verbose=()  # -cl-nv-verbose is NVIDIA's own option (another device, as in QUICK checks on a CPU, gets none)
printf '%s\n' "$devs" | sed 's/^\*/ /' | awk -v d="$GPU" '$1 == d' | grep -q NVIDIA && verbose=(--extra -cl-nv-verbose)
if [ -s "$work/built_gpu.tsv" ] && step kernels_gpu "kernel variants, verbose build" gpu 40 "$BIN/bench_kernels" "$work/built_gpu.tsv" --device "$GPU" "${verbose[@]}"; then
  if [ ${#verbose[@]} -eq 0 ]; then
    sec "Not an NVIDIA device: no ptxas report. bench_kernels printed:" ""
    show kernels_gpu 20
  else
    sec "| file | options | kernel | registers | stack [B] | spill stores [B] | spill loads [B] | warps per SM |" "|---|---|---|---|---|---|---|---|"
    awk -F'\t' '
      NF == 6 && $1 ~ /\.cl$/ { file = $1; opts = $2; next }
      /Compiling entry function/ { match($0, /\047[^\047]*\047/); k = substr($0, RSTART + 1, RLENGTH - 2) }
      /bytes stack frame/ { split($0, w, " "); st = w[1]; ss = w[5]; sl = w[9] }
      /Used [0-9]+ registers/ { match($0, /Used [0-9]+/); r = substr($0, RSTART + 5, RLENGTH - 5) + 0
        wp = int(65536 / (int((r * 32 + 255) / 256) * 256)); if (wp > 64) wp = 64
        printf "| %s | %s | %s | %d | %s | %s | %s | %d |\n", file, opts, k, r, st, ss, sl, wp }' "$work/kernels_gpu.out" >> "$work/sec_$CUR.md"
  fi
else
  sec "No table: $STATUS." ""
  show kernels_gpu 20
fi
sec ""
render

# --- 5. the benchmark programs ---
CUR=40
sec "## Benchmark programs (build/bench), GPU and CPU" ""
sec "PRTBAKE_DEVICE selects the device of bench_env, bench_lut, bench_prefilter and bench_glossy (and of the prtbake commands they start); bench_transport and bench_preview take --device." ""
bench() {  # ID TITLE DEVNAME LIMIT CMD...: one benchmark program, its output in the report
  local id=$1 title=$2 dn=$3 lim=$4; shift 4
  step "$id" "$title" "$dn" "$lim" "$@"
  sec "### $title ($dn): $STATUS, $WALL s" "" "\`$(printf '%s ' "$@" | sed "s|$G/||g; s|$work/||g")\`" ""
  show "$id"
  sec ""
}
bench b_transport_gpu bench_transport gpu 60 "$BIN/bench_transport" --device "$GPU" "${BT[@]}"
bench b_transport_cpu bench_transport cpu 60 "$BIN/bench_transport" --device "$CPU" "${BT[@]}"
for lanes in 1 8 32; do  # the scalar kernels' work-items per vertex (TransportOptions::rayLanes; 32 the GPU's default)
  bench "b_transport_lanes$lanes" "bench_transport --knot, $lanes work-items per vertex" gpu 45 \
    "$BIN/bench_transport" --device "$GPU" --knot "${BT[@]}" --packet-width 0 --ray-lanes "$lanes"
done
bench b_env_gpu "bench_env --kernel-only" gpu 45 env PRTBAKE_DEVICE="$GPU" "$BIN/bench_env" --kernel-only
bench b_env_cpu "bench_env --kernel-only" cpu 45 env PRTBAKE_DEVICE="$CPU" "$BIN/bench_env" --kernel-only
bench b_preview_gpu bench_preview gpu 45 "$BIN/bench_preview" --device "$GPU" "${BP[@]}"
bench b_preview_cpu bench_preview cpu 45 "$BIN/bench_preview" --device "$CPU" "${BP[@]}"
bench b_prefilter_gpu "bench_prefilter timing" gpu 45 env PRTBAKE_DEVICE="$GPU" "$BIN/bench_prefilter" timing "$HDR" --runs "$PF_RUNS"
bench b_prefilter_cpu "bench_prefilter timing" cpu 45 env PRTBAKE_DEVICE="$CPU" "$BIN/bench_prefilter" timing "$HDR" --runs "$PF_RUNS"
bench b_pfacc_gpu "bench_prefilter accuracy (128², 512 texels)" gpu 45 env PRTBAKE_DEVICE="$GPU" "$BIN/bench_prefilter" accuracy "$HDR" --size 128 --texels 512 --method cut
for dn in gpu cpu; do
  dev=$GPU; [ $dn = cpu ] && dev=$CPU
  bench "b_glossy_$dn" bench_glossy $dn 75 env PRTBAKE_DEVICE="$dev" "$BIN/bench_glossy" "${BG[@]}" --dir "$work/glossy_$dn"
  [ "$STATUS" != OK ] && amend "b_glossy_$dn" "$work/glossy_$dn/time.log"
  if [ "$STATUS" != OK ] && [ -f "$work/glossy_$dn/bumpy.obj" ] && [ ! -x /usr/bin/time ]; then
    # bench_glossy times its commands with /usr/bin/time -v: without it, its bake on its mesh here.
    bench "b_glossy_cli_$dn" "glossy bake without /usr/bin/time: prtbake transport bumpy.obj --transfer matrix" $dn 45 \
      "$PRTBAKE" transport "$work/glossy_$dn/bumpy.obj" -o "$work/glossy_$dn/m.npy" --transfer matrix --order 5 --samples 1024 --device "$dev"
  fi
done
mkdir -p "$work/lut_gpu" "$work/lut_cpu"
bench b_lut_gpu bench_lut gpu 120 env PRTBAKE_DEVICE="$GPU" "$BIN/bench_lut" "$work/lut_gpu"
[ -f "$work/lut_gpu/lut.json" ] && cp "$work/lut_gpu/lut.json" "$RES/lut_gpu.json"
bench b_lut_cpu bench_lut cpu 120 env PRTBAKE_DEVICE="$CPU" "$BIN/bench_lut" "$work/lut_cpu"
render
echo "bench_gpu.sh: $SECONDS s; report $REPORT" | tee -a "$LOG"
