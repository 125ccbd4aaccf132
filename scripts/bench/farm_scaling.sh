#!/usr/bin/env bash
# Render-farm scaling (issue 16; a benchmark, not a test): a graph through the local Slurm
# cluster (scripts/ci/slurm-local.sh) with 1 and with 2 task slots (the node's CPUs), each on a
# fresh cache. Prints per run: wall time (submit → last task ended), tasks, the mean
# submit-to-start delay of tasks whose dependencies were met (Slurm's EligibleTime → StartTime,
# 1 s resolution), and the mean per-task overhead = task time − the time `vfxgraph exec`
# itself reports (process start, graph load, keys and cache reads); then the wall ratio.
#   scripts/bench/farm_scaling.sh [GRAPH] [extra submit args…]
# Default: graphs/book_shot.yaml, --chunk 10 (the 240-frame book shot; hours on 2 cores).
# E.g. a quick look: scripts/bench/farm_scaling.sh graphs/farm_shot.yaml --chunk 1
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
trap 'VFXGRAPH_SLURM_CPUS= scripts/ci/slurm-local.sh start >/dev/null; rm -rf "$work"' EXIT

field() { tr ' ' '\n' | sed -n "s/^$1=//p"; }
secs() { date -d "$1" +%s; }

declare -A wall
for slots in 1 2; do
  VFXGRAPH_SLURM_CPUS=$slots scripts/ci/slurm-local.sh start >/dev/null
  eval "$(scripts/ci/slurm-local.sh env)"
  : > "$slurm_dir/log/jobcomp.log"
  cache="$work/cache-$slots"
  t0=$(date +%s.%N)
  "$bin" -q submit "$graph" --farm slurm --cache "$cache" "${extra[@]}" >/dev/null
  while squeue -h -o %j | grep -q "^$name/"; do sleep 0.5; done
  t1=$(date +%s.%N)
  wall[$slots]=$(echo "$t1 - $t0" | bc)
  tasks=0 delay=0 over=0
  while read -r line; do
    s=$(secs "$(echo "$line" | field StartTime)"); e=$(secs "$(echo "$line" | field EndTime)")
    el=$(secs "$(echo "$line" | field EligibleTime)")
    delay=$((delay + s - el)); tasks=$((tasks + 1))
    id=$(echo "$line" | field JobId)
    aj=$(echo "$line" | field ArrayJobId); at=$(echo "$line" | field ArrayTaskId)
    if [ -n "$aj" ]; then tag="${aj}_${at}"; else tag="$id"; fi
    log=$(ls "$cache"/farm/*/logs/*."$tag".log 2>/dev/null | head -n1)
    ran=$(sed -n 's/.*; \([0-9.]*\) s wall$/\1/p' "$log" 2>/dev/null | tail -n1)
    over=$(echo "$over + ($e - $s) - ${ran:-0}" | bc)
  done < <(grep "Name=$name/" "$slurm_dir/log/jobcomp.log")
  printf '%d slot(s): wall %.1f s, %d tasks, submit-to-start %.2f s/task, overhead %.2f s/task\n' \
    "$slots" "${wall[$slots]}" "$tasks" "$(echo "$delay / $tasks" | bc -l)" \
    "$(echo "$over / $tasks" | bc -l)"
done
printf 'wall ratio 1 slot / 2 slots: %.2f\n' "$(echo "${wall[1]} / ${wall[2]}" | bc -l)"
