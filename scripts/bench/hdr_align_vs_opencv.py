#!/usr/bin/env python3
"""Ward's MTB alignment: vfxgraph `align_exposures` vs OpenCV AlignMTB on the same shifted stack.

Book 10.x (Ward 2003). The Memorial stack is registered, so the script makes a hand-held one:
exposure k is cut from its image at a known offset (dx_k, dy_k) (window 24 px inside the
border), exactly as crates/imaging/tests/hdr_align.rs does, and written as PNGs with a list file.
Then, in one run:
  * vfxgraph: `cargo run --release -p vfxgraph-imaging --example hdr_align` (shifts + shifted
    stack, best of RUNS, after decoding), neighbour chain (default) and direct (OpenCV's way);
  * OpenCV: AlignMTB(max_bits=6, exclude_range=4).process (shifts to the middle exposure +
    shifted images), best of RUNS, on the decoded images;
and prints, for each, how many of the 16 shifts are exact and the time ratio ours/OpenCV.

Usage: python3 scripts/bench/hdr_align_vs_opencv.py [LIST] [--runs N]
Needs: pip install opencv-python numpy.  Timings on a shared machine are noisy.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
DEFAULT_LIST = os.path.join(ROOT, "..", "shared", "data", "debevec_memorial",
                            "memorial.hdr_image_list.txt")
sys.path.insert(0, HERE)
from hdr_vs_opencv import parse_list  # noqa: E402


def best_of(runs, fn):
    best, out = float("inf"), None
    for _ in range(runs):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("list", nargs="?", default=DEFAULT_LIST)
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    if not os.path.exists(a.list):
        print(f"data not found: {a.list}", file=sys.stderr)
        return 2
    entries = parse_list(a.list)
    n, m = len(entries), 24
    offsets = [((k * 7) % 23 - 11, (k * 5) % 17 - 8) for k in range(n)]
    r = n // 2
    truth = [(offsets[r][0] - dx, offsets[r][1] - dy) for dx, dy in offsets]
    tmp = tempfile.mkdtemp(prefix="hdr_align_")
    bgr = []
    with open(os.path.join(tmp, "list.txt"), "w") as f:
        f.write(f"{n}\n")
        for k, ((path, secs), (dx, dy)) in enumerate(zip(entries, offsets)):
            im = cv2.imread(path, cv2.IMREAD_COLOR)
            h, w = im.shape[:2]
            cut = np.ascontiguousarray(im[m - dy:h - m - dy, m - dx:w - m - dx])
            cv2.imwrite(os.path.join(tmp, f"e{k:02d}.png"), cut)
            bgr.append(cut)
            f.write(f"e{k:02d}.png {secs!r}\n")

    subprocess.run(["cargo", "build", "--release", "-q", "-p", "vfxgraph-imaging",
                    "--example", "hdr_align"], cwd=ROOT, check=True)
    exe = os.path.join(ROOT, "target", "release", "examples", "hdr_align")
    ours = {}
    for chain in ["neighbours", "reference"]:
        res = subprocess.run([exe, os.path.join(tmp, "list.txt"), str(a.runs), chain],
                             cwd=ROOT, check=True, capture_output=True, text=True)
        ours[chain] = json.loads(res.stdout.strip().splitlines()[-1])

    mtb = cv2.createAlignMTB(6, 4, True)
    t_cv, _ = best_of(a.runs, lambda: mtb.process(bgr, [None] * n))
    # The shifts OpenCV's process() applies: (0, 0) for the middle exposure, else
    # calculateShift(middle, image) on grey images made with COLOR_RGB2GRAY, as process() does.
    grey = [cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in bgr]
    cv_shifts = [(0, 0) if k == r else tuple(int(v) for v in mtb.calculateShift(grey[r], g))
                 for k, g in enumerate(grey)]

    def exact(shifts):
        return sum(tuple(s) == t for s, t in zip(shifts, truth))

    print(f"stack: {n} x {bgr[0].shape[1]}x{bgr[0].shape[0]} cut from {a.list} at known offsets")
    print(f"truth (shift to the middle exposure): {truth}")
    for chain, o in ours.items():
        print(f"vfxgraph {chain:10s}: {exact(o['shifts']):2d}/{n} exact, align {o['align_s']:.4f} s "
              f"({o['threads']} threads)")
    print(f"OpenCV AlignMTB     : {exact(cv_shifts):2d}/{n} exact, process {t_cv:.4f} s  "
          f"shifts {cv_shifts}")
    for chain, o in ours.items():
        print(f"time ratio ours ({chain}) / OpenCV = {o['align_s'] / t_cv:.3f}  "
              f"(best of {a.runs}; noisy machine)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
