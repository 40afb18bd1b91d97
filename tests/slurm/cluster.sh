#!/usr/bin/env bash
# A throw-away single-node Slurm cluster for tests, all state under DIR.
#   cluster.sh start DIR   writes DIR/slurm.conf, starts munged, slurmctld and slurmd
#                          (as root), waits until the node is idle; prints
#                          "export SLURM_CONF=DIR/slurm.conf". Exit 3: Slurm or
#                          munge is not installed; 1: it did not come up (see DIR/*.log).
#   cluster.sh stop DIR    stops the daemons it started, by the PIDs it recorded.
# Works without systemd (containers, CI). Needs root: the daemons run as root,
# munged as the munge user.
set -euo pipefail
cmd=${1:-}; dir=${2:-}
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }

stop() {
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

for c in munged slurmctld slurmd sbatch squeue scontrol sinfo setpriv; do
  command -v "$c" >/dev/null 2>&1 || { echo "not installed: $c" >&2; exit 3; }
done
id munge >/dev/null 2>&1 || { echo "no munge user" >&2; exit 3; }
[ "$(id -u)" = 0 ] || { echo "needs root" >&2; exit 3; }

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
for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
[ -S "$socket" ] || { echo "munged did not start (see $dir/munged.out)" >&2; stop; exit 1; }

# Ports from the directory name, so that two test clusters on one host do not collide.
base=$(( 20000 + $(printf '%s' "$dir" | cksum | cut -d' ' -f1) % 20000 ))
node=$(slurmd -C | sed -n 's/^\(NodeName=.*\)$/\1/p' | head -1)
host=$(printf '%s' "$node" | sed 's/^NodeName=\([^ ]*\).*/\1/')
cat >"$dir/slurm.conf" <<CONF
ClusterName=prtbaketest
SlurmctldHost=$host
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
$node State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -D -f "$SLURM_CONF" >"$dir/slurmctld.out" 2>&1 &
echo $! >"$dir/slurmctld.started-pid"
slurmd -D -f "$SLURM_CONF" >"$dir/slurmd.out" 2>&1 &
echo $! >"$dir/slurmd.started-pid"
for _ in $(seq 300); do
  state=$(sinfo -h -o %T 2>/dev/null | head -1 || true)
  [ "$state" = idle ] && { echo "export SLURM_CONF=$SLURM_CONF"; exit 0; }
  sleep 0.1
done
echo "the node did not become idle (state '${state:-}'; see $dir/slurmctld.log, $dir/slurmd.log)" >&2
stop
exit 1
