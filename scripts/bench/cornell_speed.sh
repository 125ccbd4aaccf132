#!/usr/bin/env bash
# Speed of our path tracer on the book's Cornell box against the book's `ptrace`
# (chapter 9: 640x480, 3 bounces; 162.5 CPU-seconds for 20 spp on a 2-core x86-64 VM = 37 809 paths per
# CPU-second). Same scene, resolution, spp and depth; CPU seconds from /proc (utime + stime), so a
# busy machine inflates wall time but not the figure much. Best of N runs (timings are noisy).
#   scripts/bench/cornell_speed.sh [SPP=20] [RUNS=3] [THREADS=2]
set -euo pipefail
cd "$(dirname "$0")/../.."
spp=${1:-20}; runs=${2:-3}; threads=${3:-2}
scn=../shared/data/book-demo/cornell.scn
[ -f "$scn" ] || { echo "missing $scn" >&2; exit 1; }
cargo build --release -q -p vfxgraph-render --example render_scn
best=0
for i in $(seq "$runs"); do
  line=$(./target/release/examples/render_scn "$scn" --spp "$spp" --max-depth 3 --threads "$threads" --seed "$i")
  echo "$line"
  pps=$(echo "$line" | sed -E 's/.*"paths_per_cpu_second": ([0-9]+).*/\1/')
  [ "$pps" -gt "$best" ] && best=$pps
done
book=$(( 640 * 480 * 20 * 10 / 1625 ))
echo "best: $best paths per CPU-second; book's ptrace: $book; speed-up: $(echo "scale=1; $best / $book" | bc)x (goal >= 20x)"
