#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, for testing Hydra's submitit_slurm launcher for real
# (tests/test_sweeps.py, `pytest -m slow`). Read it as the minimum a cluster config needs.
#
#   bash scripts/slurm_local.sh up   DIR   # install (Debian slurm-wlm + munge) if missing, start
#   bash scripts/slurm_local.sh down DIR   # stop the daemons started by `up DIR`
#   export SLURM_CONF=DIR/slurm.conf       # then sinfo / sbatch / srun (and submitit) use it
#
# Everything the cluster writes (state, spool, logs, pid files) stays under DIR. Needs root (the
# daemons run as root; munged as the munge user) and no systemd.
set -euo pipefail
cmd=${1:?usage: slurm_local.sh up|down DIR}
dir=$(realpath -m "${2:?usage: slurm_local.sh up|down DIR}")

if [ "$cmd" = down ]; then
  for d in slurmd slurmctld; do
    [ -f "$dir/$d.pid" ] && kill "$(cat "$dir/$d.pid")" 2>/dev/null || true
  done
  # munged is shared by everything on the machine that uses munge: stop it only if we started it
  [ -f "$dir/munged.started" ] && [ -f /run/munge/munged.pid ] && kill "$(cat /run/munge/munged.pid)" 2>/dev/null || true
  exit 0
fi
[ "$cmd" = up ] || { echo "usage: slurm_local.sh up|down DIR" >&2; exit 2; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends slurm-wlm munge
fi
mkdir -p "$dir/spool" "$dir/state"

# munge: SLURM's authentication. The package creates /etc/munge/munge.key (owner munge, 0400).
mkdir -p /run/munge && chown munge:munge /run/munge
if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
  su -s /bin/sh munge -c munged
  touch "$dir/munged.started"
  for _ in $(seq 20); do munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && break; sleep 0.25; done
fi

host=$(hostname -s)
cpus=$(nproc)
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 * 8 / 10 ))  # MiB, below the machine's
cat > "$dir/slurm.conf" <<EOF
ClusterName=local
SlurmctldHost=$host
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SlurmUser=root
ReturnToService=2
MpiDefault=none
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmdSpoolDir=$dir/spool
StateSaveLocation=$dir/state
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
JobCompType=jobcomp/none
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 60); do
  sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && { echo "slurm up: SLURM_CONF=$SLURM_CONF"; exit 0; }
  sleep 0.5
done
echo "slurm did not come up; logs in $dir" >&2
tail -5 "$dir/slurmctld.log" "$dir/slurmd.log" >&2 || true
exit 1
