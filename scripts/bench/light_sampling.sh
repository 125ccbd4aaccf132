#!/usr/bin/env bash
# Light sampling by area (book §9.11) vs by solid angle (Arvo 1995) on the book's Cornell box:
# same spp, depth 3; reports the mean variance of the pixel means, the CPU time, and the
# efficiency ratio (1 / (variance x CPU-seconds)) of solid angle over area (> 1: solid angle wins).
#   scripts/bench/light_sampling.sh [SPP=32] [WIDTH=320] [HEIGHT=240] [THREADS=2]
set -euo pipefail
cd "$(dirname "$0")/../.."
spp=${1:-32}; w=${2:-320}; h=${3:-240}; threads=${4:-2}
scn=../shared/data/book-demo/cornell.scn
[ -f "$scn" ] || { echo "missing $scn" >&2; exit 1; }
cargo build --release -q -p vfxgraph-render --example render_scn
declare -A var cpu
for mode in area solid_angle; do
  line=$(./target/release/examples/render_scn "$scn" --spp "$spp" --max-depth 3 --threads "$threads" \
         --width "$w" --height "$h" --seed 1 --light-sampling "$mode")
  echo "$line"
  var[$mode]=$(echo "$line" | sed -E 's/.*"mean_variance": ([0-9.e+-]+).*/\1/')
  cpu[$mode]=$(echo "$line" | sed -E 's/.*"cpu_seconds": ([0-9.]+).*/\1/')
done
python3 - "${var[area]}" "${cpu[area]}" "${var[solid_angle]}" "${cpu[solid_angle]}" <<'PY'
import sys
va, ca, vs, cs = map(float, sys.argv[1:])
print(f"variance ratio solid_angle/area: {vs/va:.3f}; CPU ratio: {cs/ca:.3f}; "
      f"efficiency ratio (solid_angle over area): {(va*ca)/(vs*cs):.3f}")
PY
