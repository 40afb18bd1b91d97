#!/usr/bin/env bash
# A throw-away single-node Slurm cluster for tests, all state under DIR.
#   cluster.sh start DIR   writes DIR/slurm.conf, starts munged, slurmctld and slurmd
#                          (as root), waits until the node is idle; prints
#                          "export SLURM_CONF=DIR/slurm.conf".
#   cluster.sh stop DIR    stops the daemons it started, by the PIDs it recorded.
# Exit codes of start: 0 up; 3 a cluster cannot run here (not root, Slurm or Munge
# not installed, no cgroup filesystem, a daemon that exits at once: the reason is the
# last line on stderr); 1 the daemons run but the node did not become idle in time.
# On failure stderr ends with the daemons' own last log lines. Every wait is bounded
# in seconds (START_TIMEOUT, default 60). Works without systemd (containers, CI).
set -euo pipefail
cmd=${1:-}; dir=${2:-}
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }

stop() {
  local name f pid
  for name in slurmd slurmctld munged; do
    f="$dir/$name.started-pid"
    [ -f "$f" ] || continue
    pid=$(cat "$f")
    if kill -0 "$pid" 2>/dev/null; then
      kill "$pid" 2>/dev/null || true
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -9 "$pid" 2>/dev/null || true
    fi
    rm -f "$f"
  done
}

if [ "$cmd" = stop ]; then stop; exit 0; fi
[ "$cmd" = start ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }

cannot() { echo "cannot run a test cluster here: $*" >&2; exit 3; }
for c in munged slurmctld slurmd sbatch squeue scontrol sinfo setpriv; do
  command -v "$c" >/dev/null 2>&1 || cannot "$c is not installed (apt-get install slurm-wlm munge)"
done
id munge >/dev/null 2>&1 || cannot "no munge user (apt-get install munge)"
[ "$(id -u)" = 0 ] || cannot "not root (the daemons run as root)"
# slurmd reads its node's resources through the cgroup filesystem.
[ -n "$(ls -A /sys/fs/cgroup 2>/dev/null)" ] || cannot "no cgroup filesystem at /sys/fs/cgroup (mount -t cgroup2 none /sys/fs/cgroup)"
timeout_s=${START_TIMEOUT:-60}
deadline=$(( $(date +%s) + timeout_s ))

# The daemons' last log lines, for a failure message.
logs() {
  local f
  for f in "$dir/munge/munged.log" "$dir/munged.out" "$dir/slurmctld.log" "$dir/slurmctld.out" "$dir/slurmd.log" "$dir/slurmd.out"; do
    [ -s "$f" ] || continue
    echo "--- last lines of $f:" >&2
    tail -n 15 "$f" >&2
  done
}
# Fails with exit 3 when a daemon this script started has exited.
check_alive() {
  local name f
  for name in munged slurmctld slurmd; do
    f="$dir/$name.started-pid"
    [ -f "$f" ] || continue
    if ! kill -0 "$(cat "$f")" 2>/dev/null; then
      logs
      stop
      cannot "$name exited at start (its log is above)"
    fi
  done
}

mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
chmod 755 "$dir"
mkdir -p "$dir/munge" "$dir/ctld" "$dir/spool"
chown munge:munge "$dir/munge"
chmod 755 "$dir/munge"  # munged wants the socket directory searchable by all
key="$dir/munge/munge.key"
if [ ! -f "$key" ]; then
  dd if=/dev/urandom bs=1 count=1024 of="$key" status=none
  chown munge:munge "$key"
  chmod 400 "$key"
fi
socket="$dir/munge/munge.socket.2"
setpriv --reuid=munge --regid=munge --init-groups \
  munged -F --key-file="$key" --socket="$socket" --pid-file="$dir/munge/munged.pid" \
  --seed-file="$dir/munge/munged.seed" --log-file="$dir/munge/munged.log" >"$dir/munged.out" 2>&1 &
echo $! >"$dir/munged.started-pid"
while [ ! -S "$socket" ] && [ "$(date +%s)" -lt "$deadline" ]; do check_alive; sleep 0.1; done
[ -S "$socket" ] || { logs; stop; echo "munged did not open its socket within ${timeout_s} s" >&2; exit 1; }

# Ports from the directory name, so that two test clusters on one host do not collide.
base=$(( 20000 + $(printf '%s' "$dir" | cksum | cut -d' ' -f1) % 20000 ))
node=$(timeout 20 slurmd -C | sed -n 's/^\(NodeName=.*\)$/\1/p' | head -1) || true
[ -n "$node" ] || { stop; cannot "slurmd -C did not describe this node"; }
host=$(printf '%s' "$node" | sed 's/^NodeName=\([^ ]*\).*/\1/')
# Every address is loopback, so the host name need not resolve.
cat >"$dir/slurm.conf" <<CONF
ClusterName=prtbaketest
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$base
SlurmdPort=$((base + 1))
AuthType=auth/munge
AuthInfo=socket=$socket
StateSaveLocation=$dir/ctld
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MailProg=/bin/true
ReturnToService=2
MinJobAge=600
SchedulerParameters=sched_interval=1
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -D -f "$SLURM_CONF" >"$dir/slurmctld.out" 2>&1 &
echo $! >"$dir/slurmctld.started-pid"
slurmd -D -N "$host" -f "$SLURM_CONF" >"$dir/slurmd.out" 2>&1 &
echo $! >"$dir/slurmd.started-pid"
state=""
while [ "$(date +%s)" -lt "$deadline" ]; do
  check_alive
  state=$(timeout 5 sinfo -h -o %T 2>/dev/null | head -1 || true)
  [ "$state" = idle ] && { echo "export SLURM_CONF=$SLURM_CONF"; exit 0; }
  sleep 0.2
done
logs
stop
echo "the node did not become idle within ${timeout_s} s (state '${state:-}'; the daemons' logs are above)" >&2
exit 1
