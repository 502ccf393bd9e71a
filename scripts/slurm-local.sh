#!/usr/bin/env bash
# A single-node SLURM on this machine (slurmctld + slurmd on localhost), for
# trying the job templates in jobs/ and for their test (scripts/test-slurm.sh).
#   scripts/slurm-local.sh up     write slurm.conf for this machine's CPUs and
#                                 memory, start munged, slurmctld and slurmd
#   scripts/slurm-local.sh down   stop the daemons it started (by their PIDs)
# Needs root and Debian's slurm-wlm and munge (scripts/install-deps.sh --slurm).
# An existing /etc/slurm/slurm.conf that this script did not write is left alone.
set -euo pipefail
conf=/etc/slurm/slurm.conf
state=/var/spool/tridem-slurm
mark="# written by tridem scripts/slurm-local.sh"

up() {
  command -v slurmctld >/dev/null || { echo "slurm-local: slurm-wlm is not installed (scripts/install-deps.sh --slurm)" >&2; exit 1; }
  if [ -f "$conf" ] && ! grep -qF "$mark" "$conf"; then
    echo "slurm-local: $conf exists and was not written by this script: using it as it is" >&2
  else
    local cpus mem
    cpus=$(nproc)
    mem=$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
    mkdir -p /etc/slurm "$state/ctld" "$state/d"
    cat > "$conf.new" <<CONF
$mark
ClusterName=tridem
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=pmix
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
ReturnToService=2
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/d
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$state/slurmctld.log
SlurmdLogFile=$state/slurmd.log
NodeName=localhost CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
    mv "$conf.new" "$conf"
  fi
  if ! pgrep -x munged >/dev/null; then
    mkdir -p /run/munge && chown munge:munge /run/munge 2>/dev/null || true
    [ -f /etc/munge/munge.key ] || { mungekey --create 2>/dev/null || create-munge-key; }
    if id munge >/dev/null 2>&1; then su -s /bin/sh munge -c munged 2>/dev/null || munged --force; else munged --force; fi
  fi
  pgrep -x slurmctld >/dev/null || slurmctld
  # The node is named localhost whatever the hostname is.
  pgrep -x slurmd >/dev/null || slurmd -N localhost
  for _ in $(seq 1 30); do
    if sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
      echo "slurm-local: up ($(sinfo -h -o '%D node, %c CPUs, %m MB'))" >&2
      return 0
    fi
    scontrol update nodename=localhost state=resume >/dev/null 2>&1 || true
    sleep 1
  done
  echo "slurm-local: the node did not come up; see $state/slurmctld.log and $state/slurmd.log" >&2
  exit 1
}

down() {
  for d in slurmd slurmctld; do
    if [ -f "$state/$d.pid" ]; then
      kill "$(cat "$state/$d.pid")" 2>/dev/null || true
      rm -f "$state/$d.pid"
    fi
  done
  echo "slurm-local: down" >&2
}

case "${1:-}" in
  up) up ;;
  down) down ;;
  *) echo "usage: scripts/slurm-local.sh up|down" >&2; exit 2 ;;
esac
