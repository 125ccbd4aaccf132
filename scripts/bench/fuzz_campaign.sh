#!/usr/bin/env bash
# The long fuzzing campaign (docs/validation/fuzzing.md): every target of `vfxgraph-fuzz`
# (every reader of a user file) gets its seeds and INPUTS mutated inputs (default 10^6) of run
# seed SEED (default 0), release build, decoders on one thread. Prints the table per target and
# the findings, each with its saved input (under CRASH_DIR) and the command that reproduces it,
# then the wall time and the supervisor's and workers' peak memory. Exit status: 0 when nothing
# was found, 1 when something was. Takes ~15-20 minutes on 2 cores; not part of CI (the CI
# budget is crates/fuzz/tests/ci_budget.rs).
#   scripts/bench/fuzz_campaign.sh [SEED] [--inputs N] [--target NAME]... [--crash-dir DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
seed=0
inputs=1000000
crash_dir=$here/fuzz-crashes
targets=()
while [ $# -gt 0 ]; do
  case $1 in
    --inputs) inputs=$2; shift 2 ;;
    --target) targets+=(--target "$2"); shift 2 ;;
    --crash-dir) crash_dir=$2; shift 2 ;;
    [0-9]*) seed=$1; shift ;;
    *) echo "usage: $0 [SEED] [--inputs N] [--target NAME]... [--crash-dir DIR]" >&2; exit 2 ;;
  esac
done
cd "$here"
cargo build --release --locked -p vfxgraph-fuzz >&2
echo "vfxgraph-fuzz campaign: seed $seed, $inputs inputs per target, $(nproc) cores, $(uname -sm)," \
  "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
# The campaign re-executes its binary for every worker: a private copy, so a build of the
# workspace during the run cannot swap it.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp "${CARGO_TARGET_DIR:-$here/target}/release/vfxgraph-fuzz" "$work/vfxgraph-fuzz"
start=$(date +%s)
status=0
# The workers are the supervisor's children: time's %M is the largest resident size of the
# supervisor and every worker it waited for.
/usr/bin/time -f "peak resident memory %M KiB" \
  "$work/vfxgraph-fuzz" --inputs "$inputs" --seed "$seed" --threads 1 \
  --crash-dir "$crash_dir" --progress 250000 ${targets[@]+"${targets[@]}"} || status=$?
echo "wall time $(( $(date +%s) - start )) s"
exit "$status"
