#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, for running scripts/verify_slurm.sh (and the test
# that does) without a real cluster. Needs Debian's slurmctld, slurmd, slurm-client and munge and
# root (the daemons run as root); .ci/run installs them in CI. Nothing is written outside DIR:
# the configuration is DIR/slurm.conf, used through SLURM_CONF, with its own ports (6917, 6918) so
# that it does not meet a Slurm already running here.
#
#   eval "$(scripts/slurm_localhost.sh start DIR)"   # starts munged (if needed), slurmctld, slurmd;
#                                                    # prints `export SLURM_CONF=DIR/slurm.conf`
#   scripts/slurm_localhost.sh stop DIR              # stops the two Slurm daemons started here
set -euo pipefail
cmd=${1:-}
dir=${2:-}
if [ -z "$cmd" ] || [ -z "$dir" ]; then
  echo "usage: $0 start|stop DIR" >&2
  exit 2
fi
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
conf=$dir/slurm.conf
case "$cmd" in
  start)
    for p in slurmctld slurmd munged sbatch; do
      command -v "$p" > /dev/null || [ -x "/usr/sbin/$p" ] || { echo "$0: $p is not installed" >&2; exit 3; }
    done
    [ "$(id -u)" -eq 0 ] || { echo "$0: the Slurm daemons need root" >&2; exit 3; }
    node=$(hostname -s)
    cpus=$(nproc)
    mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
    mkdir -p "$dir/state" "$dir/spool" "$dir/log"
    cat > "$conf" <<CONF
# Written by scripts/slurm_localhost.sh: one node, this machine.
ClusterName=crossdyn-local
SlurmctldHost=$node
SlurmctldPort=6917
SlurmdPort=6918
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmdSpoolDir=$dir/spool
StateSaveLocation=$dir/state
SlurmUser=root
SlurmdUser=root
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
NodeName=$node CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
    if ! pgrep -x munged > /dev/null; then
      [ -s /etc/munge/munge.key ] || { echo "$0: /etc/munge/munge.key is missing (reinstall munge)" >&2; exit 3; }
      mkdir -p /run/munge && chown munge:munge /run/munge
      runuser -u munge -- /usr/sbin/munged
    fi
    SLURM_CONF=$conf /usr/sbin/slurmctld -i
    SLURM_CONF=$conf /usr/sbin/slurmd
    for _ in $(seq 1 60); do  # until the node takes jobs
      SLURM_CONF=$conf sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
      sleep 0.5
    done
    SLURM_CONF=$conf sinfo -h -o %t | grep -qE '^(idle|mix|alloc)' ||
      { echo "$0: the node did not come up; see $dir/log" >&2; exit 3; }
    echo "export SLURM_CONF=$conf"
    ;;
  stop)
    for d in slurmd slurmctld; do
      [ -s "$dir/$d.pid" ] && kill "$(cat "$dir/$d.pid")" 2> /dev/null || true
    done
    ;;
  *) echo "usage: $0 start|stop DIR" >&2; exit 2 ;;
esac
