#!/usr/bin/env bash
# A one-node Slurm cluster on this machine (loopback), for tests of `igi cluster`.
#
#   scripts/slurm-loopback.sh start STATE_DIR   writes STATE_DIR/slurm.conf, starts munged,
#                                               slurmctld and `slurmd -N localhost`, waits
#                                               until the node is idle, prints
#                                               `export SLURM_CONF=...`
#   scripts/slurm-loopback.sh stop STATE_DIR    stops them by the pids recorded at start
#
# Needs Debian's slurm-wlm and munge (`scripts/deps.sh test` installs them) and root (the
# daemons run as root: SlurmUser=root). Settings known to work on these machines:
# proctrack/linuxproc, task/none, select/cons_tres with CR_CPU, no accounting, fixed ports
# (override with IGI_SLURM_PORT, default 6817; slurmd takes the next one). MaxArraySize is
# 1001 (Slurm's default) unless IGI_SLURM_MAX_ARRAY_SIZE sets it.
set -euo pipefail
cmd=${1:?usage: slurm-loopback.sh start|stop STATE_DIR}
state=$(realpath -m "${2:?usage: slurm-loopback.sh start|stop STATE_DIR}")
port=${IGI_SLURM_PORT:-6817}

stop() {
  for d in slurmd slurmctld munged; do
    if [ -f "$state/$d.pid" ]; then
      kill "$(cat "$state/$d.pid")" 2>/dev/null || true
      rm -f "$state/$d.pid"
    fi
  done
}

if [ "$cmd" = stop ]; then
  stop
  exit 0
fi
[ "$cmd" = start ] || { echo "usage: slurm-loopback.sh start|stop STATE_DIR" >&2; exit 2; }
for b in munged slurmctld slurmd sbatch squeue sinfo; do
  command -v "$b" >/dev/null || { echo "slurm-loopback: $b not found (install slurm-wlm and munge: scripts/deps.sh test)" >&2; exit 1; }
done
[ "$(id -u)" = 0 ] || { echo "slurm-loopback: the daemons run as root (SlurmUser=root); run as root" >&2; exit 1; }
stop
mkdir -p "$state"/{ctld,spool,munge}
chmod 700 "$state/munge"
cpus=$(nproc)
mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)
cat > "$state/slurm.conf" <<EOF
ClusterName=igi-loopback
SlurmctldHost=localhost(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$state/munge/munge.socket
CredType=cred/munge
SlurmctldPort=$port
SlurmdPort=$((port + 1))
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.daemon.pid
SlurmdPidFile=$state/slurmd.daemon.pid
SlurmctldLogFile=$state/slurmctld.log
SlurmdLogFile=$state/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
MaxArraySize=${IGI_SLURM_MAX_ARRAY_SIZE:-1001}
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
key=$state/munge/munge.key
[ -f "$key" ] || { dd if=/dev/urandom of="$key" bs=1024 count=1 2>/dev/null; chmod 400 "$key"; }
export SLURM_CONF=$state/slurm.conf
munged --force --key-file="$key" --socket="$state/munge/munge.socket" \
  --pid-file="$state/munge/munged.pid" --log-file="$state/munge/munged.log" \
  --seed-file="$state/munge/munged.seed"
for _ in $(seq 50); do [ -f "$state/munge/munged.pid" ] && break; sleep 0.1; done
cp "$state/munge/munged.pid" "$state/munged.pid"
slurmctld -D -i >"$state/slurmctld.out" 2>&1 &
echo $! > "$state/slurmctld.pid"
slurmd -D -N localhost >"$state/slurmd.out" 2>&1 &
echo $! > "$state/slurmd.pid"
for _ in $(seq 120); do
  if sinfo -h -N -o '%t' 2>/dev/null | grep -qE '^(idle|mix|alloc)'; then
    echo "export SLURM_CONF=$state/slurm.conf"
    exit 0
  fi
  sleep 0.5
done
echo "slurm-loopback: the node did not come up within 60 s; logs in $state:" >&2
tail -5 "$state/slurmctld.log" "$state/slurmd.log" "$state/slurmctld.out" "$state/slurmd.out" >&2 2>/dev/null || true
stop
exit 1
