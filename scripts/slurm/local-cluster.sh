#!/bin/bash
# A one-machine Slurm cluster for trying the array-job recipe of
# docs/scale-out.md (and for tests/slurm.rs, which starts and stops it).
#
#   scripts/slurm/local-cluster.sh start DIR   # munged, slurmctld, slurmd; waits for an idle node
#   export SLURM_CONF=DIR/slurm.conf          # then sbatch, squeue, sinfo, scancel talk to it
#   scripts/slurm/local-cluster.sh stop DIR    # kills the daemons by their pid files
#
# Everything lives under DIR: the munge key and socket, slurm.conf, the state
# and spool folders, pid and log files. Nothing under /etc or /run is touched
# and nothing is installed: it needs Debian's `slurm-wlm` and `munge` (tried
# with Slurm 22.05 and munge 0.5.15 on Debian 12) and runs as root, the jobs
# too. SLURMCTLD_PORT and SLURMD_PORT (default 6817, 6818) choose the ports;
# MAX_WAIT (seconds, default 60) bounds the wait for the node.
set -euo pipefail

usage() {
    echo "usage: $0 start|stop DIR" >&2
    exit 2
}
[ $# -eq 2 ] || usage
action=$1
mkdir -p "$2"
dir=$(cd "$2" && pwd)

# Kills the daemon whose pid file is $1, if it runs, and waits for it to go.
stop_one() {
    local pidfile=$1 pid
    [ -s "$pidfile" ] || return 0
    pid=$(cat "$pidfile")
    if kill "$pid" 2>/dev/null; then
        for _ in $(seq 100); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        kill -9 "$pid" 2>/dev/null || true
    fi
    rm -f "$pidfile"
}

stop() {
    stop_one "$dir/run/slurmd.pid"
    stop_one "$dir/run/slurmctld.pid"
    stop_one "$dir/munge/munged.pid"
}

start() {
    for tool in munged slurmctld slurmd sinfo; do
        command -v "$tool" >/dev/null || {
            echo "$0: $tool not found; install Debian's slurm-wlm and munge" >&2
            exit 1
        }
    done
    [ "$(id -u)" -eq 0 ] || { echo "$0: run it as root" >&2; exit 1; }
    local node cpus mem ctld_port=${SLURMCTLD_PORT:-6817} d_port=${SLURMD_PORT:-6818}
    node=$(hostname -s)
    cpus=$(nproc)
    # 90% of the memory, in MB: slurmd drains a node that has less than it is said to.
    mem=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
    mkdir -p "$dir"/{munge,run,log,state,spool}
    # munged wants its socket's folder and every folder above it searchable by all.
    chmod 755 "$dir" "$dir/munge"

    if [ ! -s "$dir/munge/munge.key" ]; then
        head -c 1024 /dev/urandom > "$dir/munge/munge.key"
        chmod 400 "$dir/munge/munge.key"
    fi
    munged --key-file="$dir/munge/munge.key" \
        --socket="$dir/munge/munge.socket" \
        --pid-file="$dir/munge/munged.pid" \
        --log-file="$dir/munge/munged.log" \
        --seed-file="$dir/munge/munged.seed" || {
        echo "$0: munged did not start (log: $dir/munge/munged.log); it needs $dir and every folder above it searchable by all (chmod 755)" >&2
        exit 1
    }

    cat > "$dir/slurm.conf" <<CONF
# Written by scripts/slurm/local-cluster.sh: a one-machine cluster.
ClusterName=mrdrive-local
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF="$dir/slurm.conf"
    slurmctld -f "$SLURM_CONF" || { echo "$0: slurmctld did not start; log: $dir/log/slurmctld.log; then: $0 stop $dir" >&2; exit 1; }
    slurmd -f "$SLURM_CONF" || { echo "$0: slurmd did not start; log: $dir/log/slurmd.log; then: $0 stop $dir" >&2; exit 1; }

    local waited=0 state=""
    while :; do
        state=$(sinfo -h -N -o %t 2>/dev/null | head -n1 || true)
        [ "$state" = idle ] && break
        if [ "$waited" -ge "$((${MAX_WAIT:-60} * 10))" ]; then
            echo "$0: the node is not idle after ${MAX_WAIT:-60} s (state: ${state:-none}); logs in $dir/log" >&2
            tail -n 20 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 || true
            echo "$0: stop the daemons with: $0 stop $dir" >&2
            exit 1
        fi
        sleep 0.1
        waited=$((waited + 1))
    done
    echo "local Slurm up: node $node idle, $cpus CPUs; export SLURM_CONF=$SLURM_CONF"
}

case $action in
    start) start ;;
    stop) stop ;;
    *) usage ;;
esac
