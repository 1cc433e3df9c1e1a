#!/bin/sh
# A one-node Slurm cluster on this machine, without systemd, for trying `myriad slurm` and for
# its test: munged, slurmctld and slurmd with a private configuration, state and sockets in DIR.
#
#   scripts/slurm-local.sh start DIR   # then: export SLURM_CONF=DIR/slurm.conf
#   scripts/slurm-local.sh stop DIR    # stops the daemons it started (by their pid files)
#
# Needs Debian's slurm-wlm, slurm-client and munge (apt-get install -y --no-install-recommends
# slurm-wlm munge slurm-client). Ports: SLURM_LOCAL_PORT (default 16817) and the next one.
set -eu
cmd=${1:-}
dir=${2:-}
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }

stop() {
  for p in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
    if [ -s "$p" ]; then
      kill "$(cat "$p")" 2>/dev/null || true
    fi
  done
  # Wait for them to go, so that the ports are free for the next cluster.
  for _ in $(seq 50); do
    alive=0
    for p in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
      # (A zombie has exited: where nothing reaps orphans it stays one.)
      [ -s "$p" ] && kill -0 "$(cat "$p")" 2>/dev/null &&
        ! grep -q '^State:.*Z' "/proc/$(cat "$p")/status" 2>/dev/null && alive=1
    done
    [ $alive = 0 ] && break
    sleep 0.1
  done
  rm -f "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"
}

case "$cmd" in
stop) stop; exit 0 ;;
start) ;;
*) echo "usage: $0 start|stop DIR" >&2; exit 2 ;;
esac

for b in munged slurmctld slurmd sbatch; do
  command -v $b >/dev/null 2>&1 || [ -x /usr/sbin/$b ] || { echo "$b not found: install slurm-wlm munge slurm-client" >&2; exit 3; }
done
PATH=$PATH:/usr/sbin
mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
dir=$(cd "$dir" && pwd)
chmod 700 "$dir/munge"
[ -s "$dir/munge/munge.key" ] || {
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 2>/dev/null
  chmod 400 "$dir/munge/munge.key"
}
munged --force --socket="$dir/munge/munge.socket" --key-file="$dir/munge/munge.key" \
  --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/seed"
host=$(hostname -s)
user=$(id -un)
port=${SLURM_LOCAL_PORT:-16817}
cpus=$(nproc)
cat > "$dir/slurm.conf" <<CONF
ClusterName=myriad-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
MinJobAge=600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=main Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -i
slurmd
# Ready when the node is idle (under a second here).
for _ in $(seq 100); do
  state=$(sinfo -h -o %T 2>/dev/null || true)
  [ "$state" = idle ] && { echo "export SLURM_CONF=$dir/slurm.conf"; exit 0; }
  sleep 0.2
done
echo "slurm did not come up (node: ${state:-no answer}); logs in $dir/log" >&2
stop
exit 1
