#!/usr/bin/env bash
# A one-node Slurm cluster on this host, for the farm tests (tests/farm.rs) and benchmarks:
#   scripts/ci/slurm-local.sh start   # munged (if not running), slurmctld, slurmd; waits idle,
#                                     # then checks both daemons stay up (exit 1 and their
#                                     # logs' tails if not, e.g. another Slurm holds the ports)
#   scripts/ci/slurm-local.sh stop    # stops only the daemons this script started
#   scripts/ci/slurm-local.sh env     # prints `export SLURM_CONF=…` for the shell
# Idempotent. Runs as root without systemd (Debian's slurm-wlm + munge). Everything it writes
# (slurm.conf, state, spool, logs, pid files, the job completion log) is in
# $VFXGRAPH_SLURM_DIR (default /tmp/vfxgraph-slurm); /etc/slurm is not touched, so every
# Slurm command needs SLURM_CONF=$VFXGRAPH_SLURM_DIR/slurm.conf (`env` prints it).
# VFXGRAPH_SLURM_CPUS sets the node's CPUs (task slots; default nproc); `start` after a change
# restarts the daemons with the new value.
set -euo pipefail
dir="${VFXGRAPH_SLURM_DIR:-/tmp/vfxgraph-slurm}"
conf="$dir/slurm.conf"
host="$(hostname -s)"
cpus="${VFXGRAPH_SLURM_CPUS:-$(nproc)}"
# The node's memory (MiB), so jobs with a --mem hint fit (Slurm's default is 1 MiB): 95 % of
# it, never above what slurmd detects.
mem="$(awk '/^MemTotal:/ {print int($2 / 1024 * 0.95)}' /proc/meminfo)"
export SLURM_CONF="$conf"

# True when pid file $1 names a live process of daemon $2 (default: the file's name), not
# another process that reused a dead daemon's pid.
alive() {
  local pid name="${2:-$(basename "$1" .pid)}"
  pid="$(cat "$1" 2>/dev/null)" || return 1
  [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || return 1
  [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$name" ]
}

# The controller that answers on our config is ours: its state folder is ours (another
# cluster on the same ports would answer with its own).
ours_answers() {
  local state
  state="$(scontrol show config 2>/dev/null | awk -F' = ' '$1 ~ /^StateSaveLocation/ {print $2}')"
  [ "$state" = "$dir/state" ]
}

# The size of daemon $1's log, so a failure shows only what this start logged.
log_size() { stat -c %s "$dir/log/$1.log" 2>/dev/null || echo 0; }
declare -A log_from=([slurmctld]=0 [slurmd]=0)

# The last lines our daemons logged since this start, on stderr.
log_tails() {
  for d in slurmctld slurmd; do
    echo "--- $dir/log/$d.log (the last 15 lines of this start)" >&2
    tail -c +"$((log_from[$d] + 1))" "$dir/log/$d.log" 2>/dev/null | tail -n 15 >&2 || true
  done
}

# Fails (log tails, the daemons this call started stopped, exit 1) with message $1.
fail() {
  echo "slurm-local: $1" >&2
  log_tails
  if [ "${started:-0}" = 1 ]; then stop_slurm; fi
  exit 1
}

write_conf() {
  mkdir -p "$dir"/{state,spool,log}
  cat > "$conf.new" <<CONF
ClusterName=vfxgraph
SlurmctldHost=$host
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
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
# Start a job as soon as its dependency is met or a slot frees (the default batch_sched_delay
# of 3 s, for clusters flooded with submissions, made a one-slot farm idle ~2 s per task).
SchedulerParameters=batch_sched_delay=0
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$dir/log/jobcomp.log
MinJobAge=600
MaxArraySize=10001
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=farm Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
  if ! cmp -s "$conf.new" "$conf" 2>/dev/null; then
    if alive "$dir/slurmctld.pid" || alive "$dir/slurmd.pid"; then stop_slurm; fi
    mv "$conf.new" "$conf"
  else
    rm -f "$conf.new"
  fi
}

start_munge() {
  if runuser -u munge -- munge -n </dev/null >/dev/null 2>&1 && pgrep -x munged >/dev/null; then
    return
  fi
  for d in /run/munge /var/log/munge /var/lib/munge /etc/munge; do
    mkdir -p "$d"
    chown munge:munge "$d"
  done
  chmod 0755 /run/munge
  chmod 0700 /var/log/munge /var/lib/munge /etc/munge
  if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
    chown munge:munge /etc/munge/munge.key
    chmod 0400 /etc/munge/munge.key
  fi
  runuser -u munge -- munged
  touch "$dir/started-munged"
}

stop_slurm() {
  for d in slurmd slurmctld; do
    if alive "$dir/$d.pid"; then
      # The daemon may remove its pid file between the check and the read.
      kill "$(cat "$dir/$d.pid" 2>/dev/null)" 2>/dev/null || true
      for _ in $(seq 50); do alive "$dir/$d.pid" || break; sleep 0.1; done
    fi
    rm -f "$dir/$d.pid"
  done
}

start() {
  write_conf
  start_munge
  started=0
  if alive "$dir/slurmctld.pid" && alive "$dir/slurmd.pid"; then
    echo "slurm: already running from $dir (slurmctld $(cat "$dir/slurmctld.pid"), slurmd $(cat "$dir/slurmd.pid"))"
  else
    started=1
    for d in slurmctld slurmd; do
      if ! alive "$dir/$d.pid"; then
        log_from[$d]="$(log_size "$d")"
        "$d" -f "$conf" || fail "$d -f $conf failed to start"
      fi
    done
  fi
  local state="" up=0
  for _ in $(seq 100); do
    state="$(sinfo -h -N -n "$host" -o %t 2>/dev/null | head -n1 || true)"
    case "$state" in
      idle|mix|alloc) up=1; break ;;
      down*|drain*) scontrol update nodename="$host" state=resume 2>/dev/null || true ;;
    esac
    sleep 0.2
  done
  [ "$up" = 1 ] || fail "node $host did not come up (state '${state:-no answer}')"
  # A daemon that cannot bind its port (another Slurm holds it) dies a moment after it
  # forked, while the other cluster answers `sinfo`: the daemons must still be alive after a
  # couple of seconds, and the controller answering must be ours.
  sleep 2
  for d in slurmctld slurmd; do
    alive "$dir/$d.pid" || fail "$d is not running (pid file $dir/$d.pid)"
  done
  ours_answers || fail "the controller answering on $conf is not this one (state $dir/state): another Slurm on this host's ports?"
  state="$(sinfo -h -N -n "$host" -o %t 2>/dev/null | head -n1 || true)"
  case "$state" in
    idle|mix|alloc) echo "slurm: node $host ($cpus CPUs) $state; export SLURM_CONF=$conf" ;;
    *) fail "node $host is ${state:-not answering} after the start" ;;
  esac
}

stop() {
  stop_slurm
  if [ -f "$dir/started-munged" ]; then
    if [ -f /run/munge/munged.pid ]; then kill "$(cat /run/munge/munged.pid)" 2>/dev/null || true; fi
    rm -f "$dir/started-munged"
  fi
  echo "slurm: stopped"
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  env) echo "export SLURM_CONF=$conf" ;;
  *) echo "usage: $0 start|stop|env" >&2; exit 2 ;;
esac
