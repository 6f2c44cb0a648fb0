#!/usr/bin/env bash
# A single-node SLURM on this machine, for testing the cohort workflow (workflow/) for real; run as root.
#   scripts/slurm-local.sh start DIR   munge (if it is not already running), slurmctld and slurmd with their
#                                       configuration, state and logs under DIR; prints DIR/slurm.conf (export
#                                       SLURM_CONF=DIR/slurm.conf to use the cluster)
#   scripts/slurm-local.sh stop DIR    stops what start started (by the pid files under DIR)
# Needs `scripts/install-deps.sh workflow`. No systemd: the daemons are started and stopped by hand.
set -euo pipefail
what=${1:?usage: slurm-local.sh start|stop DIR}
dir=${2:?usage: slurm-local.sh start|stop DIR}

stop_pid_file() {  # TERM, up to 10 s, then KILL
  local f=$1 pid
  [ -s "$f" ] || return 0
  pid=$(cat "$f")
  kill -TERM "$pid" 2>/dev/null || { rm -f "$f"; return 0; }
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  kill -KILL "$pid" 2>/dev/null || true
  rm -f "$f"
}

if [ "$what" = stop ]; then
  stop_pid_file "$dir/slurmd.pid"
  stop_pid_file "$dir/slurmctld.pid"
  stop_pid_file "$dir/munged.pid"  # only if start started it
  exit 0
fi
[ "$what" = start ] || { echo "usage: slurm-local.sh start|stop DIR" >&2; exit 2; }

mkdir -p "$dir"/{state,spool,log}
dir=$(cd "$dir" && pwd)

# munge: used as it is if it answers; else its key and run folder made and munged started (its pid recorded).
if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
  if [ ! -s /etc/munge/munge.key ]; then
    mungekey --create --keyfile=/etc/munge/munge.key
    chown munge:munge /etc/munge/munge.key
    chmod 400 /etc/munge/munge.key
  fi
  install -d -o munge -g munge -m 0755 /run/munge
  runuser -u munge -- /usr/sbin/munged
  for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
  cp /run/munge/munged.pid "$dir/munged.pid"
  munge -n | unmunge >/dev/null || { echo "slurm-local: munge does not work" >&2; exit 1; }
fi

host=$(hostname -s)
node=$(slurmd -C | head -n1)
cat >"$dir/slurm.conf" <<CONF
ClusterName=mskseg-local
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
SchedulerParameters=batch_sched_delay=0
MpiDefault=none
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 150); do
  [ "$(sinfo -h -o %T 2>/dev/null | head -n1)" = idle ] && { echo "$SLURM_CONF"; exit 0; }
  sleep 0.2
done
echo "slurm-local: the node did not become idle within 30 s (see $dir/log/)" >&2
exit 1
