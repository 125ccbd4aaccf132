#!/usr/bin/env bash
# A chain of N nodes (default 100 000): `check` and `plan` wall time and peak memory, then a
# fresh `run -q` with its most threads (sampled from /proc) and peak memory, then the cached
# rerun. Goals: check and plan under 2 s; the run on at most cores + 8 threads and < 2 GB.
#
#   scripts/bench/large_graph.sh [N]
set -euo pipefail
n=${1:-100000}
root=$(cd "$(dirname "$0")/../.." && pwd)
cargo build --release --quiet --manifest-path "$root/Cargo.toml"
bin="$root/target/release/vfxgraph"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 - "$n" "$dir/g.yaml" <<'PY'
import sys
n, path = int(sys.argv[1]), sys.argv[2]
with open(path, "w") as f:
    f.write("version: 1\nnodes:\n  n0: {type: constant, params: {width: 2, height: 2}}\n")
    for i in range(1, n):
        f.write(f"  n{i}: {{type: exposure, inputs: {{image: n{i-1}.image}}, params: {{stops: 0.001}}}}\n")
PY
cd "$dir"
timed() { /usr/bin/time -f "%e %M" "$@" 2>&1 >/dev/null | tail -1; }
read -r t m < <(timed "$bin" check g.yaml)
printf '%-14s %8.2f s %8.0f MB\n' check "$t" "$((m / 1024))"
read -r t m < <(timed "$bin" plan g.yaml)
printf '%-14s %8.2f s %8.0f MB\n' plan "$t" "$((m / 1024))"
/usr/bin/time -f "%e %M" -o time.txt "$bin" run -q g.yaml &
sleep 0.2
pid=$(pgrep -n -f "$bin run -q g.yaml" || true)
most=0
while [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; do
    t=$(awk '/^Threads/{print $2}' "/proc/$pid/status" 2>/dev/null || true)
    [ -n "$t" ] && [ "$t" -gt "$most" ] && most=$t
    sleep 0.05
done
wait
read -r t m < time.txt
printf '%-14s %8.2f s %8.0f MB  %d threads at most on %d cores\n' "run (fresh)" "$t" "$((m / 1024))" "$most" "$(nproc)"
read -r t m < <(timed "$bin" run -q g.yaml)
printf '%-14s %8.2f s %8.0f MB\n' "run (cached)" "$t" "$((m / 1024))"
