#!/usr/bin/env bash
# How fast a long 4K HEVC clip reads into the graph, against FFmpeg's own decode, in one run
# (`vfxgraph bench video`), and the peak resident memory of the read. A benchmark, not a test.
#   scripts/bench/video_decode.sh [SECONDS]     # default 60: a 1-minute clip
# Makes the clip once (FFmpeg's testsrc2 with temporal grain, 3840×2160, 24 fps, HEVC Main 10
# by libx265 `ultrafast`, in $VFXGRAPH_BENCH_DIR, default /tmp/vfxgraph-video-bench), then reads
# it with the release build. Needs ffmpeg/ffprobe with libx265 on the PATH.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds="${1:-60}"
dir="${VFXGRAPH_BENCH_DIR:-/tmp/vfxgraph-video-bench}"
clip="$dir/hevc10_4k_${seconds}s.mp4"
mkdir -p "$dir"
if [ ! -s "$clip" ]; then
  echo "making $clip (${seconds} s of 4K HEVC Main 10) …" >&2
  ffmpeg -v error -y -f lavfi -i "testsrc2=size=3840x2160:rate=24,noise=alls=12:allf=t" \
    -t "$seconds" -c:v libx265 -preset ultrafast -x265-params log-level=error \
    -pix_fmt yuv420p10le -tag:v hvc1 "$clip.tmp.mp4"
  mv "$clip.tmp.mp4" "$clip"
fi
cargo build --release --quiet
echo "$(nproc) cores; load before: $(cut -d' ' -f1-3 /proc/loadavg)"
target/release/vfxgraph bench video "$clip" "${@:2}"
