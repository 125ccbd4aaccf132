#!/usr/bin/env python3
"""KLT benchmark: vfxgraph's tracker (crates/klt/src) against OpenCV's
goodFeaturesToTrack + calcOpticalFlowPyrLK, in one run, on the same frames and corners.

    pip install opencv-python-headless numpy
    python3 scripts/bench/klt_vs_opencv.py [--repeat 15] [--rounds 3]

Frames: a real photograph (Oxford VGG Merton College I, ../shared/data) resized to 1280x720
and 1920x1080, blurred (sigma 1) and warped by a known sub-pixel affine motion (0.37 px,
-0.61 px translation plus a 0.3 degree rotation about the centre) with Lanczos-4 resampling.
Both trackers get the same 8-bit gray frames, the same window (21), pyramid levels (3),
iterations (30) and epsilon (0.01), and track the SAME corners (OpenCV's), so the accuracy
is compared point for point: median end-point error against the known motion, and the
fraction tracked. Times are the best of --repeat runs (wall clock, all cores for both:
OpenCV's parallel_for and our rayon); "track" = both pyramids + LK of every feature
(calcOpticalFlowPyrLK on images; ours: two pyramid builds + track_points), the ratio
column compares that equal work; "seq ms" is ours with one pyramid, our per-frame cost in a
sequence (each frame's pyramid is built once and reused as the next frame's "previous").
Also: Middlebury RubberWhale, median end-point error against the ground-truth flow on the
same corners for both trackers.

On a machine shared with other work, times vary from run to run; the best of many repeats
(15), in rounds (3) that alternate OpenCV and ours, is the figure least disturbed by others,
for both sides alike.
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

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.path.join(os.path.dirname(ROOT), "shared", "data")
WIN, LEVELS, ITERS, EPS = 21, 3, 30, 0.01
CRIT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, ITERS, EPS)


def best(f, repeat):
    t = float("inf")
    out = None
    for _ in range(repeat):
        s = time.perf_counter()
        out = f()
        t = min(t, time.perf_counter() - s)
    return t, out


def ours(a_png, b_png, pts, features, repeat):
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
        for x, y in pts:
            f.write(f"{x} {y}\n")
        cpath = f.name
    exe = os.path.join(ROOT, "target", "release", "examples", "klt_bench")
    out = subprocess.run(
        [exe, a_png, b_png, cpath, str(features), str(WIN), str(LEVELS), str(ITERS), str(repeat)],
        check=True, capture_output=True, text=True).stdout
    os.unlink(cpath)
    return json.loads(out)


def epe(tracked, truth):
    ok = [i for i, p in enumerate(tracked) if p is not None]
    if not ok:
        return float("nan"), 0.0
    e = [np.hypot(tracked[i][0] - truth[i][0], tracked[i][1] - truth[i][1]) for i in ok]
    return float(np.median(e)), len(ok) / len(tracked)


def opencv_track(a, b, pts, repeat):
    # OpenCV 5's Python binding no longer takes prebuilt pyramids, so OpenCV builds both
    # pyramids in each call; our time below adds a second pyramid build to match.
    p0 = np.array(pts, np.float32).reshape(-1, 1, 2)

    def run():
        return cv2.calcOpticalFlowPyrLK(a, b, p0, None, winSize=(WIN, WIN), maxLevel=LEVELS,
                                        criteria=CRIT)

    t, (p1, st, _) = best(run, repeat)
    tracked = [tuple(p1[i, 0]) if st[i, 0] == 1 else None for i in range(len(pts))]
    return t, tracked


def synthetic(w, h, workdir):
    src = cv2.imread(os.path.join(DATA, "oxford_vgg_merton_college_I", "images", "001.jpg"),
                     cv2.IMREAD_GRAYSCALE)
    src = cv2.resize(src, (w, h), interpolation=cv2.INTER_AREA if w < src.shape[1] else cv2.INTER_CUBIC)
    src = cv2.GaussianBlur(src.astype(np.float32), (0, 0), 1.0)
    c = ((w - 1) / 2, (h - 1) / 2)
    m = cv2.getRotationMatrix2D(c, -0.3, 1.0)  # maps A's pixel to B's (y down)
    m[0, 2] += 0.37
    m[1, 2] += -0.61
    a = np.clip(np.rint(src), 0, 255).astype(np.uint8)
    b = cv2.warpAffine(src, m, (w, h), flags=cv2.INTER_LANCZOS4, borderMode=cv2.BORDER_REFLECT101)
    b = np.clip(np.rint(b), 0, 255).astype(np.uint8)
    pa, pb = os.path.join(workdir, f"a{w}.png"), os.path.join(workdir, f"b{w}.png")
    cv2.imwrite(pa, a)
    cv2.imwrite(pb, b)
    return a, b, pa, pb, m


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    if not os.path.isdir(DATA):
        print(f"no data at {DATA}; nothing to do")
        return 0
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "vfxgraph-klt", "--example",
                    "klt_bench"], cwd=ROOT, check=True)
    print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads; best of {args.repeat} x "
          f"{args.rounds} rounds; "
          f"window {WIN}, levels {LEVELS}, iterations {ITERS}, eps {EPS}")
    hdr = ("size", "feat", "corners ms ours/cv", "ratio", "track ms ours/cv", "ratio",
           "seq ms", "us/feat ours/cv", "median EPE ours/cv", "tracked ours/cv")
    print("{:>9} {:>5} {:>19} {:>6} {:>17} {:>6} {:>6} {:>15} {:>19} {:>15}".format(*hdr))
    with tempfile.TemporaryDirectory() as wd:
        for (w, h) in [(1280, 720), (1920, 1080)]:
            a, b, pa, pb, m = synthetic(w, h, wd)
            for n in [150, 2000]:
                tc, corners = best(lambda: cv2.goodFeaturesToTrack(a, n, 0.01, 10, blockSize=3), args.repeat)
                pts = [tuple(map(float, p)) for p in corners.reshape(-1, 2)]
                truth = [tuple(m @ np.array([x, y, 1.0])) for x, y in pts]
                # Rounds alternate the two sides so that a burst of load from other work
                # hits both alike; each side keeps its best time over all rounds.
                tt, cv_pts = opencv_track(a, b, pts, args.repeat)
                r = ours(pa, pb, pts, n, args.repeat)
                for _ in range(args.rounds - 1):
                    tc = min(tc, best(lambda: cv2.goodFeaturesToTrack(a, n, 0.01, 10, blockSize=3),
                                      args.repeat)[0])
                    tt = min(tt, opencv_track(a, b, pts, args.repeat)[0])
                    r2 = ours(pa, pb, pts, n, args.repeat)
                    for k in ("corners_ms", "track_ms", "pyramid_ms"):
                        r[k] = min(r[k], r2[k])
                seq_ms = r["track_ms"]  # one pyramid + LK: our per-frame cost in a sequence
                r["track_ms"] += r["pyramid_ms"]  # + the previous frame's pyramid = OpenCV's work
                e_cv, f_cv = epe(cv_pts, truth)
                e_us, f_us = epe(r["points"], truth)
                print("{:>9} {:>5} {:>8.2f} / {:>8.2f} {:>6.2f} {:>7.2f} / {:>7.2f} {:>6.2f} {:>6.2f} "
                      "{:>6.1f} / {:>6.1f} {:>8.4f} / {:>8.4f} {:>6.1%} / {:>6.1%}".format(
                          f"{w}x{h}", len(pts), r["corners_ms"], tc * 1e3, r["corners_ms"] / (tc * 1e3),
                          r["track_ms"], tt * 1e3, r["track_ms"] / (tt * 1e3), seq_ms,
                          1e3 * r["track_ms"] / len(pts), 1e6 * tt / len(pts), e_us, e_cv, f_us, f_cv))
        # RubberWhale: real motion with ground-truth flow.
        rw = os.path.join(DATA, "middlebury_flow_RubberWhale")
        a = cv2.imread(os.path.join(rw, "frame10.png"), cv2.IMREAD_GRAYSCALE)
        b = cv2.imread(os.path.join(rw, "frame11.png"), cv2.IMREAD_GRAYSCALE)
        raw = np.fromfile(os.path.join(rw, "flow10.flo"), np.float32)
        fw, fh = raw[1:3].view(np.int32)
        flow = raw[3:].reshape(fh, fw, 2)
        pa, pb = os.path.join(wd, "rw10.png"), os.path.join(wd, "rw11.png")
        cv2.imwrite(pa, a)
        cv2.imwrite(pb, b)
        corners = cv2.goodFeaturesToTrack(a, 500, 0.01, 10, blockSize=3)
        pts = [tuple(map(float, p)) for p in corners.reshape(-1, 2)]
        _, cv_pts = opencv_track(a, b, pts, 1)
        r = ours(pa, pb, pts, 500, 1)
        keep = [i for i, (x, y) in enumerate(pts) if np.all(np.abs(flow[int(y), int(x)]) < 1e9)]
        truth = [(pts[i][0] + flow[int(pts[i][1]), int(pts[i][0])][0],
                  pts[i][1] + flow[int(pts[i][1]), int(pts[i][0])][1]) for i in keep]
        e_us, f_us = epe([r["points"][i] for i in keep], truth)
        e_cv, f_cv = epe([cv_pts[i] for i in keep], truth)
        both = [i for i in keep if r["points"][i] is not None and cv_pts[i] is not None]
        tb = {i: t for i, t in zip(keep, truth)}
        e_us_b, _ = epe([r["points"][i] for i in both], [tb[i] for i in both])
        e_cv_b, _ = epe([cv_pts[i] for i in both], [tb[i] for i in both])
        print(f"RubberWhale ({len(keep)} corners with known flow): median EPE ours {e_us:.4f} px "
              f"({f_us:.1%} tracked), OpenCV {e_cv:.4f} px ({f_cv:.1%} tracked); on the {len(both)} "
              f"tracked by both: ours {e_us_b:.4f}, OpenCV {e_cv_b:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
