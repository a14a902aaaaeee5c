#!/bin/bash
# A one-node Slurm cluster on this machine, for the farm tests:
#   scripts/slurm-cluster.sh up     install slurm-wlm and munge when absent,
#                                   write slurm.conf for this host and its
#                                   cores, start munged, slurmctld, slurmd
#   scripts/slurm-cluster.sh down   stop the daemons `up` started (by
#                                   their pid files), never others
# Runs as root without systemd. State lives in /var/lib/prism-slurm.
set -euo pipefail

STATE=/var/lib/prism-slurm
CONF=/etc/slurm/slurm.conf
MUNGE_PID=/run/munge/prism-munged.pid

# Whether a live process (not a zombie) named $1 runs.
running() {
    local pid
    for pid in $(pgrep -x "$1"); do
        [ "$(awk '{print $3}' "/proc/$pid/stat" 2>/dev/null)" != Z ] && return 0
    done
    return 1
}

pid_file() {
    case "$1" in
        munged) echo "$MUNGE_PID" ;;
        *) echo "$STATE/$1.pid" ;;
    esac
}

up() {
    if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
        echo "installing slurm-wlm and munge from Debian ..." >&2
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null
    fi
    local host cpus mem
    host=$(hostname -s)
    cpus=$(nproc)
    # Leave the system some memory; Slurm refuses nodes that report less
    # than slurm.conf says.
    mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 * 9 / 10 ))
    mkdir -p /etc/munge /var/log/munge /run/munge /var/lib/munge "$STATE"/{ctld,d} /etc/slurm
    if [ ! -s /etc/munge/munge.key ]; then
        dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
    fi
    chown -R munge:munge /etc/munge /var/log/munge /run/munge /var/lib/munge 2>/dev/null || true
    chmod 0400 /etc/munge/munge.key
    cat > "$CONF" <<CONF
ClusterName=prism
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
ReturnToService=2
StateSaveLocation=$STATE/ctld
SlurmdSpoolDir=$STATE/d
SlurmctldPidFile=$STATE/slurmctld.pid
SlurmdPidFile=$STATE/slurmd.pid
SlurmctldLogFile=$STATE/slurmctld.log
SlurmdLogFile=$STATE/slurmd.log
MaxArraySize=100001
MinJobAge=300
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=main Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    # A daemon already running (the host's own) is used, not restarted,
    # and `down` leaves it alone: only those started here are recorded.
    if ! running munged; then
        # munged's own folder: it may run as the munge user.
        su -s /bin/sh munge -c "munged --force --pid-file=$MUNGE_PID" 2>/dev/null ||
            munged --force --pid-file="$MUNGE_PID"
        echo munged >> "$STATE/started"
    fi
    if ! running slurmctld; then
        slurmctld
        echo slurmctld >> "$STATE/started"
    fi
    if ! running slurmd; then
        slurmd
        echo slurmd >> "$STATE/started"
    fi
    # Wait for the node to be idle.
    for _ in $(seq 1 60); do
        if sinfo --noheader --format=%T 2>/dev/null | grep -q idle; then
            sinfo
            return 0
        fi
        scontrol update nodename="$host" state=resume >/dev/null 2>&1 || true
        sleep 1
    done
    echo "slurm did not come up; see $STATE/*.log" >&2
    sinfo >&2 || true
    return 1
}

down() {
    [ -f "$STATE/started" ] || return 0
    local name pid
    for name in slurmd slurmctld munged; do
        grep -qx "$name" "$STATE/started" || continue
        pid=$(cat "$(pid_file "$name")" 2>/dev/null || true)
        # The pid must still be that daemon, not a process that reused it.
        if [ -n "$pid" ] && [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$name" ]; then
            kill "$pid" || true
        fi
    done
    rm -f "$STATE/started"
    sleep 1
}

case "${1:-}" in
    up) up ;;
    down) down ;;
    *) echo "usage: $0 up|down" >&2; exit 2 ;;
esac
