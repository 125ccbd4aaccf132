#!/usr/bin/env bash
# Render-farm scaling (issue 16; a benchmark, not a test): a graph through the local Slurm
# cluster (scripts/ci/slurm-local.sh) with 1 and with 2 task slots (the node's CPUs), each on a
# fresh cache. Prints per run: wall time (submit → last task ended), tasks, the mean
# submit-to-start delay of tasks whose dependencies were met (Slurm's EligibleTime → StartTime,
# 1 s resolution), the mean process overhead of a task (its log's start/end stamps minus the
# run `vfxgraph exec` itself reports: process start, graph load, keys, cache reads), and the
# mean time per task outside any computation ((wall − Σ exec runs) / tasks; with 1 slot every
# task runs alone, so this is all the farm's overhead: scheduling, dependency release,
# process start); the compute seconds of the nodes that run once (the serial part: tracks,
# solve) and of the per-frame ones; then the wall ratio.
#   scripts/bench/farm_scaling.sh [GRAPH] [extra submit args…]
# Default: graphs/book_shot.yaml, --chunk 10 (the book shot; at its full settings hours on 2
# cores). The figures in ARCHITECTURE.md (farm section):
#   scripts/bench/farm_scaling.sh graphs/book_shot.yaml --frames 0..240 --chunk 10 \
#     --set shot.width=320 --set shot.height=180 --set shot.spp=64
# Needs a release build (cargo build --release; or VFXGRAPH_BIN=…) and root (it restarts the
# local cluster, and leaves it running with all CPUs).
set -euo pipefail
cd "$(dirname "$0")/../.."
graph="${1:-graphs/book_shot.yaml}"
shift || true
extra=("$@")
[ ${#extra[@]} -gt 0 ] || extra=(--chunk 10)
bin="${VFXGRAPH_BIN:-$PWD/target/release/vfxgraph}"
[ -x "$bin" ] || { echo "build first: cargo build --release" >&2; exit 2; }
name="$(basename "$graph" .yaml)"
work="$(mktemp -d /tmp/vfxgraph-farm-bench.XXXXXX)"
slurm_dir="${VFXGRAPH_SLURM_DIR:-/tmp/vfxgraph-slurm}"
# Slurm starts every job in a new session, and with the kernel's autogroup scheduling each
# session is one group with an equal share of the CPUs whatever its processes' nice values:
# builds others run at `nice -n 19` would take as much CPU as the benchmark's tasks. For the
# run, autogroup is turned off (as root) so nice values rank processes, and turned back on.
ag=/proc/sys/kernel/sched_autogroup_enabled
ag_was="$(cat "$ag" 2>/dev/null || echo 0)"
if [ "$ag_was" = 1 ] && [ "${VFXGRAPH_BENCH_KEEP_AUTOGROUP:-}" != 1 ]; then
  echo 0 > "$ag" && echo "autogroup scheduling off for the run (VFXGRAPH_BENCH_KEEP_AUTOGROUP=1 keeps it)"
fi
trap 'echo "$ag_was" > "$ag" 2>/dev/null || true; VFXGRAPH_SLURM_CPUS= scripts/ci/slurm-local.sh start >/dev/null; rm -rf "$work"' EXIT

declare -A wall
for slots in 1 2; do
  VFXGRAPH_SLURM_CPUS=$slots scripts/ci/slurm-local.sh start >/dev/null
  eval "$(scripts/ci/slurm-local.sh env)"
  : > "$slurm_dir/log/jobcomp.log"
  cache="$work/cache-$slots"
  echo "load before $slots slot(s): $(uptime | sed 's/.*load average: //')"
  t0=$(date +%s.%N)
  "$bin" -q submit "$graph" --farm slurm --cache "$cache" "${extra[@]}" >/dev/null
  while squeue -h -o %j | grep -q "^$name/"; do sleep 0.2; done
  t1=$(date +%s.%N)
  wall[$slots]=$(echo "$t1 - $t0" | bc)
  python3 - "$slots" "${wall[$slots]}" "$name" "$slurm_dir/log/jobcomp.log" "$cache" <<'PY'
import glob, os, re, sys, datetime
slots, wall, name, jobcomp, cache = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
def field(line, k):
    m = re.search(r"(?:^| )" + k + r"=(\S*)", line)
    return m.group(1) if m else None
def secs(t):
    return datetime.datetime.fromisoformat(t).timestamp()
tasks, delay, states = 0, 0.0, {}
for line in open(jobcomp):
    if field(line, "Name") is None or not field(line, "Name").startswith(name + "/"):
        continue
    tasks += 1
    delay += secs(field(line, "StartTime")) - secs(field(line, "EligibleTime"))
    states[field(line, "JobState")] = states.get(field(line, "JobState"), 0) + 1
proc, ran, once, per_frame, logs = 0.0, 0.0, 0.0, 0.0, 0
for log in glob.glob(os.path.join(cache, "farm", "*", "logs", "*.log")):
    text = open(log).read()
    s = re.search(r"task start ([0-9.]+)", text)
    e = re.search(r"task end ([0-9.]+)", text)
    r = re.findall(r"; ([0-9.]+) s wall", text)
    if not (s and e and r):
        continue
    logs += 1
    run = float(r[-1])
    ran += run
    proc += float(e.group(1)) - float(s.group(1)) - run
    # Per-frame tasks log as <node>.<array job>_<index>.log, once tasks <node>.<job>.log.
    if re.search(r"\.\d+_\d+\.log$", log):
        per_frame += run
    else:
        once += run
print(f"{slots} slot(s): wall {wall:.1f} s, {tasks} tasks {states}; submit-to-start "
      f"{delay / max(tasks, 1):.2f} s/task (Slurm, 1 s resolution); process overhead "
      f"{proc / max(logs, 1):.3f} s/task; outside computation {(wall - ran) / max(tasks, 1):.3f} "
      f"s/task; runs: once nodes {once:.1f} s, per-frame nodes {per_frame:.1f} s")
PY
done
printf 'wall ratio 1 slot / 2 slots: %.2f\n' "$(echo "${wall[1]} / ${wall[2]}" | bc -l)"
