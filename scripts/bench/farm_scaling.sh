#!/usr/bin/env bash
# Render-farm scaling (a benchmark, not a test): a graph through the local Slurm
# cluster (scripts/ci/slurm-local.sh) with 1 and with 2 task slots (the node's CPUs), each on a
# fresh cache. Prints per run: wall time (submit → last task ended), tasks, the mean
# submit-to-start delay of tasks whose dependencies were met (Slurm's EligibleTime → StartTime,
# 1 s resolution), the mean process overhead of a task (its log's start/end stamps minus the
# run `vfxgraph exec` itself reports: process start, graph load, keys, cache reads), and the
# mean time per task outside any computation ((wall − Σ exec runs) / tasks; with 1 slot every
# task runs alone, so this is all the farm's overhead: scheduling, dependency release,
# process start); the compute seconds of the nodes that run once (the serial part: tracks,
# solve) and of the per-frame ones. Then per job: its tasks, the CPUs Slurm allocated each
# (ProcCnt), the threads each ran (`exec --jobs`, from its log), mean run and CPU seconds
# (bash's `time` of exec: user + system) and CPU/run (≈ the cores a task kept busy); how many
# tasks ran at once; the serial part (submit → the first per-frame task started) as a
# fraction of the wall. Last: the wall ratio and Amdahl's bound for 2 slots from the 1-slot
# run's serial fraction.
#   scripts/bench/farm_scaling.sh [GRAPH] [extra submit args…]
# Default: graphs/book_shot.yaml, --chunk 10 (the book shot; at its full settings hours on 2
# cores). The figures in docs/validation/benchmarks.md ("Render-farm scaling"):
#   scripts/bench/farm_scaling.sh graphs/book_shot.yaml --frames 0..240 --chunk 10 \
#     --set shot.width=320 --set shot.height=180 --set shot.spp=64 --fuse --task-cpus 1
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
# Slurm starts every job under setsid, and with the kernel's autogroup scheduling each
# such process group is one group with an equal share of the CPUs whatever its processes' nice values:
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
  # A freshly started controller makes its first scheduling pass ~3 s after it starts: one
  # warm-up job first, so the run measures a farm that is running, as a studio's is.
  sbatch -J vfxgraph-bench-warmup -o /dev/null --wrap true >/dev/null
  while squeue -h -n vfxgraph-bench-warmup | grep -q .; do sleep 0.2; done
  : > "$slurm_dir/log/jobcomp.log"
  cache="$work/cache-$slots"
  echo "load before $slots slot(s): $(uptime | sed 's/.*load average: //')"
  t0=$(date +%s.%N)
  "$bin" -q submit "$graph" --farm slurm --cache "$cache" "${extra[@]}" >/dev/null
  while squeue -h -o %j | grep -q "^$name/"; do sleep 0.2; done
  t1=$(date +%s.%N)
  wall[$slots]=$(echo "$t1 - $t0" | bc)
  python3 - "$slots" "$t0" "${wall[$slots]}" "$name" "$slurm_dir/log/jobcomp.log" "$cache" <<'PY'
import glob, os, re, sys, datetime
slots, t0, wall, name, jobcomp, cache = (sys.argv[1], float(sys.argv[2]), float(sys.argv[3]),
                                         sys.argv[4], sys.argv[5], sys.argv[6])
def field(line, k):
    m = re.search(r"(?:^| )" + k + r"=(\S*)", line)
    return m.group(1) if m else None
def secs(t):
    return datetime.datetime.fromisoformat(t).timestamp()
tasks, delay, states, alloc = 0, 0.0, {}, {}
for line in open(jobcomp):
    if field(line, "Name") is None or not field(line, "Name").startswith(name + "/"):
        continue
    tasks += 1
    delay += secs(field(line, "StartTime")) - secs(field(line, "EligibleTime"))
    states[field(line, "JobState")] = states.get(field(line, "JobState"), 0) + 1
    job = field(line, "Name").split("/")[1]
    alloc.setdefault(job, set()).add(int(field(line, "ProcCnt") or 0))
# Per task, from its log: start/end stamps, the threads it ran (its allocation's CPUs), the
# run exec reports, and bash's `time` of exec (CPU user + system).
logs = []
for log in glob.glob(os.path.join(cache, "farm", "*", "logs", "*.log")):
    text = open(log).read()
    s = re.search(r"task start ([0-9.]+) on \S+ threads (\d+)", text)
    e = re.search(r"task end ([0-9.]+)", text)
    r = re.findall(r"; ([0-9.]+) s wall", text)
    c = re.search(r"task cpu ([0-9.]+) user ([0-9.]+) sys", text)
    # exec's closing table: node, instances, cached, ran, failed, seconds (of computing).
    computed = sum(float(m) for m in re.findall(r"^\S+ +\d+ +\d+ +\d+ +\d+ +([0-9.]+)$", text, re.M))
    if not (s and e and r and c):
        continue
    base = os.path.basename(log)
    logs.append({
        "job": base.split(".")[0],
        # Per-frame tasks log as <job>.<array job>_<index>.log, once tasks <job>.<job id>.log.
        "per_frame": re.search(r"\.\d+_\d+\.log$", base) is not None,
        "start": float(s.group(1)), "end": float(e.group(1)), "threads": int(s.group(2)),
        "run": float(r[-1]), "cpu": float(c.group(1)) + float(c.group(2)), "computed": computed,
    })
n = max(len(logs), 1)
proc = sum(l["end"] - l["start"] - l["run"] for l in logs)
ran = sum(l["run"] for l in logs)
once = sum(l["run"] for l in logs if not l["per_frame"])
per_frame = sum(l["run"] for l in logs if l["per_frame"])
print(f"{slots} slot(s): wall {wall:.1f} s, {tasks} tasks {states}; submit-to-start "
      f"{delay / max(tasks, 1):.2f} s/task (Slurm, 1 s resolution); process overhead "
      f"{proc / n:.3f} s/task; outside computation {(wall - ran) / max(tasks, 1):.3f} "
      f"s/task; runs: once nodes {once:.1f} s, per-frame nodes {per_frame:.1f} s")
# "cache I/O": a one-thread task's run minus the seconds its instances computed (reading its
# inputs from the cache, storing its outputs, keys); "-" for a task with more threads.
print(f"  {'job':<34} {'tasks':>5} {'CPUs':>5} {'threads':>7} {'run s/task':>10} "
      f"{'CPU s/task':>10} {'CPU/run':>7} {'cache I/O s/task':>16}")
for job in sorted({l["job"] for l in logs}, key=lambda j: min(l["start"] for l in logs if l["job"] == j)):
    ls = [l for l in logs if l["job"] == job]
    run = sum(l["run"] for l in ls)
    cpu = sum(l["cpu"] for l in ls)
    label = job if len(job) <= 34 else f"{job.split('+')[0]}+{job.count('+')} more"
    cpus = ",".join(str(c) for c in sorted(alloc.get(job, [])))
    threads = ",".join(str(t) for t in sorted({l["threads"] for l in ls}))
    io = (f"{sum(l['run'] - l['computed'] for l in ls) / len(ls):.3f}"
          if all(l["threads"] == 1 for l in ls) else "-")
    print(f"  {label:<34} {len(ls):>5} {cpus:>5} {threads:>7} {run / len(ls):>10.3f} "
          f"{cpu / len(ls):>10.3f} {cpu / max(run, 1e-9):>7.2f} {io:>16}")
# How many tasks ran at once (from the stamps): the time-weighted mean while any ran, the
# most; and the same for the per-frame ones.
def concurrency(ls):
    ev = sorted([(l["start"], 1) for l in ls] + [(l["end"], -1) for l in ls])
    busy, area, most, cur, last = 0.0, 0.0, 0, 0, None
    for t, d in ev:
        if last is not None and cur > 0:
            busy += t - last
            area += cur * (t - last)
        cur += d
        most = max(most, cur)
        last = t
    return area / max(busy, 1e-9), most
mean_all, most_all = concurrency(logs)
pf = [l for l in logs if l["per_frame"]]
mean_pf, most_pf = concurrency(pf)
# The serial part: submit → the first per-frame task's start (the once chain and its
# dependency hops; nothing per frame can start before the solve and the placement).
first_pf = min((l["start"] for l in pf), default=t0 + wall)
serial = first_pf - t0
cpu_all = sum(l["cpu"] for l in logs)
print(f"  tasks at once: mean {mean_all:.2f}, most {most_all} (per-frame: mean {mean_pf:.2f}, "
      f"most {most_pf}); CPU of all tasks {cpu_all:.1f} s = {cpu_all / wall:.2f} cores over "
      f"the wall; serial part (submit → first per-frame task) {serial:.1f} s = "
      f"{100 * serial / wall:.1f} % of the wall, per-frame part {wall - serial:.1f} s")
# With one slot, the farm's own time per task from the stamps: submit → the first task's
# start, then each task's end → the next one's start (dependency release or the next pending
# task, Slurm's scheduling pass, job launch, bash).
if slots == "1" and logs:
    by_start = sorted(logs, key=lambda l: l["start"])
    gaps = [b["start"] - a["end"] for a, b in zip(by_start, by_start[1:])]
    print(f"  submit → first task start {by_start[0]['start'] - t0:.2f} s; the slot idle between "
          f"tasks: mean {sum(gaps) / max(len(gaps), 1):.3f} s, max {max(gaps, default=0):.3f} s")
with open(os.path.join(os.path.dirname(cache), f"serial-{slots}"), "w") as f:
    f.write(f"{serial} {wall}\n")
PY
done
printf 'wall ratio 1 slot / 2 slots: %.2f\n' "$(echo "${wall[1]} / ${wall[2]}" | bc -l)"
# Amdahl's bound for 2 slots from the 1-slot run: its serial part stays, the rest halves.
read -r s1 w1 < "$work/serial-1"
read -r s2 _ < "$work/serial-2"
printf "Amdahl's bound (1-slot serial fraction %.3f): %.2fx; with the 2-slot run's serial part: %.2fx\n" \
  "$(echo "$s1 / $w1" | bc -l)" "$(echo "$w1 / ($s1 + ($w1 - $s1) / 2)" | bc -l)" \
  "$(echo "$w1 / ($s2 + ($w1 - $s1) / 2)" | bc -l)"
echo "load after: $(uptime | sed 's/.*load average: //')"
