#!/usr/bin/env bash
# The cost of solving the lens (#21): `matchmove` on the distorted dev plate's tracks with the
# focal length and k1 k2 unknown (graphs/dev_plate_lens.yaml) against the same solve given the
# true lens (focal: known, the renderer's K and Brown–Conrady coefficients as an intrinsics
# JSON). The tracks are computed once (cached); each solve is then forced RUNS times,
# alternating, and the fastest of each is compared. Prints both and their ratio.
#   scripts/bench/lens_solve_cost.sh [--vfxgraph target/release/vfxgraph] [--runs 3]
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
bin=$here/target/release/vfxgraph
runs=3
while [ $# -gt 0 ]; do
  case $1 in
    --vfxgraph) bin=$(realpath "$2"); shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    *) echo "usage: $0 [--vfxgraph BIN] [--runs N]" >&2; exit 2 ;;
  esac
done
data=${VFXGRAPH_SHARED_DATA:-$here/../shared/data}/blender_plate_dev/distorted
[ -d "$data/plate" ] || { echo "no plate at $data (set VFXGRAPH_SHARED_DATA)" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/lens.json" <<JSON
{"K": [[920.0, 0, 479.5], [0, 920.0, 269.5], [0, 0, 1]], "width": 960, "height": 540,
 "distortion": {"model": "brown_conrady", "k1": -0.16, "k2": 0.045, "p1": 0.0008, "p2": -0.0005}}
JSON
cat > "$work/graph.yaml" <<YAML
version: 1
seed: 1
frames: 0..48
nodes:
  plate: {type: read_image_sequence, params: {path: "$data/plate/frame.%04d.jpg"}}
  track: {type: klt_track, inputs: {frames: plate.sequence}}
  lens: {type: read_intrinsics, params: {path: "$work/lens.json"}}
  unknown:
    type: matchmove
    inputs: {tracks: track.tracks}
    params: {focal: unknown, distortion: k1k2, width: 960, height: 540}
  known:
    type: matchmove
    inputs: {tracks: track.tracks, intrinsics: lens.intrinsics}
YAML
"$bin" run "$work/graph.yaml" -q
seconds() {
  "$bin" run "$work/graph.yaml" --force "$1" --json -q | python3 -c "
import json, sys
print(sum(n['seconds'] for n in json.load(sys.stdin)['nodes'] if n['id'] == '$1'))"
}
us=(); ks=()
for _ in $(seq "$runs"); do
  us+=("$(seconds unknown)"); ks+=("$(seconds known)")
done
python3 -c "
u, k = min([$(IFS=,; echo "${us[*]}")]), min([$(IFS=,; echo "${ks[*]}")])
print(f'lens unknown (focal + k1 k2): {u:.2f} s; lens known: {k:.2f} s; ratio {u / k:.2f}x (goal <= 2x)')"
