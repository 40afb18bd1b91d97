#!/usr/bin/env bash
# `prtbake queue` under load with faults, at the size of the issue: tests/queue/load.py with 4
# workers over 500 small job files (about 1000 lut and env jobs), most of them arriving while the
# workers run, workers killed at random (SIGKILL, 1 s apart on average) and restarted, workers
# paused (SIGSTOP) past --stale-after (3 s) until another worker has taken their claim back, then
# continued, and a --drain worker at the end. RUNS rounds (default 3; round N uses seed N). Every
# round must pass the script's checks (nothing lost or duplicated, every output equal to a
# reference `prtbake run`'s, no temp file left); the figures go to bench/results/queue.md.
#   bash bench/bench_queue.sh [PRTBAKE]     (PRTBAKE: default build/prtbake)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PRTBAKE=$(realpath "${1:-$ROOT/build/prtbake}")
[ -x "$PRTBAKE" ] || { echo "bench_queue.sh: $PRTBAKE is not an executable" >&2; exit 2; }
OUT=$ROOT/bench/results/queue.md
RUNS=${RUNS:-3}
FILES=${FILES:-500}
PAUSES=${PAUSES:-3}
work=$(mktemp -d /tmp/prtbake-bench-queue.XXXXXX)
trap 'rm -rf "$work"' EXIT
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$work/pocl-cache}
load=$(cut -d' ' -f1-3 /proc/loadavg)
for run in $(seq "$RUNS"); do
  /usr/bin/python3 "$ROOT/tests/queue/load.py" --prtbake "$PRTBAKE" --files "$FILES" --pauses "$PAUSES" \
    --seed "$run" --json "$work/round$run.json" > "$work/round$run.txt" 2>&1 ||
    { cat "$work/round$run.txt" >&2; echo "bench_queue.sh: round $run failed its checks" >&2; exit 1; }
  tail -n 1 "$work/round$run.txt"
done
{
  echo "# Queue under load with faults (bench/bench_queue.sh)"
  echo
  echo "bench/bench_queue.sh, $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)); PoCL $(dpkg-query -W -f='${Version}' pocl-opencl-icd 2>/dev/null || echo '?'), CPU device; load average $load before the runs (the machine shared with other work); $RUNS rounds, round N with seed N:"
  echo
  echo '```'
  echo "/usr/bin/python3 tests/queue/load.py --prtbake build/prtbake --files $FILES --pauses $PAUSES --seed N --json FILE"
  echo '```'
  echo
  echo "4 workers (\`prtbake queue DIR --poll 0.05 --stale-after 3 --quiet --log-json\`); a tenth of the job files submitted before the workers start, the rest in waves while they run (written elsewhere or under a hidden name, then renamed into \`pending/\`); a worker killed with SIGKILL on average every second (mostly one holding a claim) and a new one started at once; $PAUSES times a worker holding a claim stopped with SIGSTOP until another worker has taken the claim back (more than \`--stale-after\` later), then continued; at the end the pool killed and one \`--drain\` worker finishing what is left (about a tenth). Each job file holds 1 to 3 jobs: \`lut\` (size 8-16, 16-64 samples) or \`env\` (a lat-long HDR of at most 32 x 16 texels, order 1-6), writing EXR, JSON, games202 text and a few PNG outputs; 2 % of the files hold an invalid job on purpose and must end in \`failed/\`."
  echo
  /usr/bin/python3 - "$work" "$RUNS" <<'EOF'
import json, statistics, sys
work, runs = sys.argv[1], int(sys.argv[2])
r = [json.load(open("%s/round%d.json" % (work, n))) for n in range(1, runs + 1)]
cols = [("seed", "round (seed)"), ("jobs", "jobs"), ("job_files", "job files"), ("kills", "kills"),
        ("restarts", "restarts"), ("pauses", "pauses"), ("wall_seconds", "wall [s]"), ("jobs_per_minute", "jobs/min"),
        ("lost", "lost"), ("duplicated", "duplicated"), ("mismatched", "mismatched"), ("temp_files_left", "temp files left")]
print("| " + " | ".join(c[1] for c in cols) + " |")
print("|" + "---|" * len(cols))
for d in r:
    print("| " + " | ".join(("%.0f" % d[k]) if k == "jobs_per_minute" else str(d[k]) for k, _ in cols) + " |")
print()
print("Median: %.0f jobs per minute (%.0f job files per minute); the same job files by one `prtbake run`, "
      "before each round, took %s s (median)." % (
          statistics.median(d["jobs_per_minute"] for d in r),
          statistics.median(d["job_files"] / d["wall_seconds"] * 60 for d in r),
          statistics.median(d["reference_seconds"] for d in r)))
print()
print("| round (seed) | claims taken back: dead worker | no sign of life | files run again | "
      "finished after their claim was taken back | temp files swept | files left for --drain | longest pause [s] |")
print("|---|---|---|---|---|---|---|---|")
for d in r:
    print("| %d | %d | %d | %d | %d | %d | %d | %.1f |" % (d["seed"], d["reclaims_dead_worker"], d["reclaims_no_sign_of_life"],
          d["reruns"], d["stale_finishes"], d["temp_files_swept"], d["left_for_drain"], d["pause_seconds_max"]))
EOF
  echo
  echo "wall: from the first worker's start to the end of the \`--drain\` worker; kills: while the pool works, each followed by a restart (the pool's SIGKILLs at the end not counted); lost: a job file in neither \`done/\` nor \`failed/\`; duplicated: in both or twice, or moved out of \`running/\` twice (the workers' \`finished\` events); mismatched: an output that differs from the reference run's (EXR, PNG and games202 text as bytes, JSON sidecars without their timings and the name the EXR was staged under); temp files left: names containing \`.prtbake-tmp.\` in the output tree or the spool. Every round also checked: each file in the right directory with its log, no failed run of a valid file, every job's manifest consistent with its outputs, and a dry run finding every job of \`done/\` up to date. Claims taken back from a dead worker also count those of the pool killed at the end (the \`--drain\` worker takes them back); those with no sign of life are the paused workers' (one each); files run again are those, plus files whose worker was killed after writing the log but before moving the file; the temp files swept are the staging files of killed workers, removed by the next job writing to the same directory."
  echo
  echo "Wall times vary between rounds with the machine's load: the runs are bound by the disk (every output, manifest and directory is fsynced) as much as by the 2 cores, which other work shared, so jobs per minute is a figure of this machine at that time."
} > "$OUT"
cat "$OUT"
