#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# A throwaway single-node Slurm cluster on 127.0.0.1, for tests and for trying `drivenshape farm
# slurm` on one machine. Everything (munge key and socket, slurm.conf, state, spool, logs, pid
# files) lives in one folder; no systemd, nothing in /etc or /var is touched.
#
#   scripts/slurm_local_cluster.sh start DIR   # install slurm-wlm/munge if missing, start munged,
#                                              # slurmctld and slurmd, wait until the node is idle
#   scripts/slurm_local_cluster.sh env DIR     # print `export SLURM_CONF=...` for clients
#   scripts/slurm_local_cluster.sh stop DIR    # stop the daemons started in DIR (by pid file)
#   scripts/slurm_local_cluster.sh stop --remove DIR   # ... and delete DIR
#
# Clients (sbatch, squeue, sinfo, scontrol) need SLURM_CONF=DIR/slurm.conf. DIR must be short
# (the munge socket path is limited to 107 bytes). Runs as root (SlurmUser=root); as another
# user only installing needs sudo, and the daemons then run as that user.
#
# Auth: auth/munge with a key generated in DIR and munged listening on DIR/munge/munge.socket
# (AuthInfo=socket=...). Daemons bind to 127.0.0.1 (CommunicationParameters=NoInAddrAny).
set -euo pipefail

die() {
  echo "slurm_local_cluster: $*" >&2
  exit 1
}

install_if_missing() {
  local missing=()
  command -v slurmctld >/dev/null 2>&1 || missing+=(slurmctld)
  command -v slurmd >/dev/null 2>&1 || missing+=(slurmd)
  command -v sbatch >/dev/null 2>&1 || missing+=(slurm-client)
  command -v munged >/dev/null 2>&1 || missing+=(munge)
  ((${#missing[@]})) || return 0
  echo "slurm_local_cluster: installing slurm-wlm munge (missing: ${missing[*]})" >&2
  local sudo=""
  [[ $(id -u) -eq 0 ]] || sudo="sudo"
  $sudo apt-get update -qq || die "apt-get update failed"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
    slurm-wlm munge >/dev/null || die "apt-get install slurm-wlm munge failed"
  for tool in slurmctld slurmd sbatch munged; do
    command -v "$tool" >/dev/null 2>&1 || die "$tool is still missing after installing"
  done
}

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# kill_pidfile FILE NAME: SIGTERM the process in FILE, wait up to 10 s, then SIGKILL it.
kill_pidfile() {
  local file=$1 name=$2 pid
  [[ -s $file ]] || return 0
  pid=$(cat "$file")
  [[ $pid =~ ^[0-9]+$ ]] || return 0
  if kill -0 "$pid" 2>/dev/null; then
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 100); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.1
    done
    if kill -0 "$pid" 2>/dev/null; then
      echo "slurm_local_cluster: $name ($pid) ignored SIGTERM; killing it" >&2
      kill -KILL "$pid" 2>/dev/null || true
    fi
  fi
  rm -f "$file"
}

show_logs() {
  local dir=$1
  for log in "$dir"/log/*.log; do
    [[ -f $log ]] || continue
    echo "---- $log (last 20 lines)" >&2
    tail -n 20 "$log" >&2
  done
}

start() {
  local dir=$1
  install_if_missing
  mkdir -p "$dir"
  dir=$(cd "$dir" && pwd)
  [[ ! -e $dir/slurm.conf ]] || die "$dir already holds a cluster; stop it first"
  local socket=$dir/munge/munge.socket
  ((${#socket} < 100)) || die "'$dir' is too long for a munge socket path; use a shorter folder"
  mkdir -p "$dir"/{munge,state,spool,log,run}
  chmod 700 "$dir/munge"
  local user
  user=$(id -un)

  # munge: a fresh key, our own socket, pid, log and seed files.
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge/munge.key"
  munged --force --key-file="$dir/munge/munge.key" --socket="$socket" \
    --pid-file="$dir/run/munged.pid" --log-file="$dir/log/munged.log" \
    --seed-file="$dir/munge/munged.seed" || { show_logs "$dir"; die "munged did not start"; }
  for _ in $(seq 50); do
    [[ -S $socket ]] && break
    sleep 0.1
  done
  munge --socket="$socket" -n </dev/null | unmunge --socket="$socket" >/dev/null ||
    { show_logs "$dir"; die "munge round trip failed on $socket"; }

  # The node as slurmd -C sees it (real CPU layout and memory), renamed to localhost.
  local node
  node=$(slurmd -C | head -n 1 | sed -e 's/^NodeName=[^ ]*//')
  [[ $node == *CPUs=* ]] || die "slurmd -C printed no node description"
  local ctld_port slurmd_port
  ctld_port=$(free_port)
  slurmd_port=$(free_port)
  while [[ $slurmd_port == "$ctld_port" ]]; do slurmd_port=$(free_port); done

  cat >"$dir/slurm.conf" <<EOF
# Written by scripts/slurm_local_cluster.sh: a single-node cluster on 127.0.0.1.
ClusterName=dsfarm
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
CommunicationParameters=NoInAddrAny,NoCtldInAddrAny
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MinJobAge=600
KillWait=10
MaxArraySize=1001
NodeName=localhost NodeAddr=127.0.0.1 NodeHostname=localhost$node State=UNKNOWN
PartitionName=local Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
  export SLURM_CONF=$dir/slurm.conf

  # -D keeps them in the foreground of their own background job; -i ignores old state.
  slurmctld -D -i -f "$SLURM_CONF" </dev/null >>"$dir/log/slurmctld.stdout" 2>&1 &
  echo $! >"$dir/run/slurmctld.pid.launch"
  slurmd -D -N localhost -f "$SLURM_CONF" </dev/null >>"$dir/log/slurmd.stdout" 2>&1 &
  echo $! >"$dir/run/slurmd.pid.launch"

  local state=""
  for _ in $(seq 600); do
    state=$(sinfo -h -N -n localhost -o '%t' 2>/dev/null || true)
    [[ $state == idle ]] && break
    for daemon in slurmctld slurmd; do
      if ! kill -0 "$(cat "$dir/run/$daemon.pid.launch")" 2>/dev/null; then
        show_logs "$dir"
        tail -n 20 "$dir/log/$daemon.stdout" >&2 || true
        die "$daemon exited during start-up"
      fi
    done
    sleep 0.1
  done
  if [[ $state != idle ]]; then
    show_logs "$dir"
    die "node 'localhost' did not become idle within 60 s (state '$state')"
  fi
  echo "slurm_local_cluster: up in $dir (slurmctld 127.0.0.1:$ctld_port, slurmd" \
    "127.0.0.1:$slurmd_port, auth/munge); export SLURM_CONF=$SLURM_CONF" >&2
}

stop() {
  local dir=$1
  [[ -d $dir ]] || return 0
  # Cancel what is still queued or running so that no job step outlives its daemons.
  if [[ -f $dir/slurm.conf ]] && [[ -s $dir/run/slurmctld.pid.launch ]] &&
    kill -0 "$(cat "$dir/run/slurmctld.pid.launch")" 2>/dev/null; then
    export SLURM_CONF=$dir/slurm.conf
    local jobs
    jobs=$(timeout 10 squeue -h -o '%A' 2>/dev/null | sort -u || true)
    if [[ -n $jobs ]]; then
      # shellcheck disable=SC2086
      timeout 10 scancel $jobs 2>/dev/null || true
      for _ in $(seq 150); do
        [[ -z $(timeout 5 squeue -h -o '%A' 2>/dev/null || true) ]] && break
        sleep 0.1
      done
    fi
  fi
  # The launch pid files hold the processes this script started; the daemons' own pid files
  # name the same processes once they are up. Each is stopped by its id, nothing by name.
  kill_pidfile "$dir/run/slurmd.pid.launch" slurmd
  kill_pidfile "$dir/run/slurmd.pid" slurmd
  kill_pidfile "$dir/run/slurmctld.pid.launch" slurmctld
  kill_pidfile "$dir/run/slurmctld.pid" slurmctld
  kill_pidfile "$dir/run/munged.pid" munged
}

case "${1:-}" in
  start)
    [[ $# -eq 2 ]] || die "usage: $0 start DIR"
    start "$2"
    ;;
  env)
    [[ $# -eq 2 ]] || die "usage: $0 env DIR"
    echo "export SLURM_CONF=$(cd "$2" && pwd)/slurm.conf"
    ;;
  stop)
    if [[ ${2:-} == --remove ]]; then
      [[ $# -eq 3 ]] || die "usage: $0 stop [--remove] DIR"
      stop "$3"
      rm -rf "$3"
    else
      [[ $# -eq 2 ]] || die "usage: $0 stop [--remove] DIR"
      stop "$2"
    fi
    ;;
  *)
    die "usage: $0 start|env|stop [--remove] DIR"
    ;;
esac
