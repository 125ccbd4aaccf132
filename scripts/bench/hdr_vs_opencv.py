#!/usr/bin/env python3
"""HDR response recovery + merge: vfxgraph vs OpenCV on the same exposure stack.

Book chapter 10.2-10.4 (Debevec & Malik 1997). Runs, in one process/run:
  * vfxgraph: `cargo run --release -p vfxgraph-imaging --example hdr_memorial` (calibrate +
    merge timed in-process, best of RUNS, after decoding);
  * OpenCV: CalibrateDebevec (defaults: 70 samples, lambda 10, grid) + MergeDebevec, and
    CalibrateRobertson, timed on the same decoded images (best of RUNS);
and reports, for every curve (ours, OpenCV Debevec, OpenCV Robertson, a plain gamma 2.2), the
exposure-consistency error computed by ONE function here:
  for each pixel and channel, the log radiances ln(f^-1(Z)/dt) over the exposures with
  32 <= Z <= 223 (pixels with >= 2 such exposures), |deviation from the per-pixel median|;
  the median over all of them. Pixels that are pure blue (0,0,255) in any exposure are masked.

Usage: python3 scripts/bench/hdr_vs_opencv.py [LIST] [--runs N] [--samples S] [--lambda L]
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


def parse_list(path):
    entries, count = [], None
    for line in open(path):
        t = line.strip()
        if not t or t.startswith("#"):
            continue
        if count is None:
            count = int(t)
            continue
        name, secs = t.split()
        if "/" in secs:
            a, b = secs.split("/")
            secs = float(a) / float(b)
        else:
            secs = float(secs)
        p = os.path.join(os.path.dirname(path), name)
        if not os.path.exists(p):
            p = os.path.splitext(p)[0] + ".png"
        entries.append((p, secs))
    assert len(entries) == count
    return entries


def consistency(codes_rgb, times, inv_resp_rgb, mask, lo=32, hi=223):
    """codes_rgb: (P,H,W,3) uint8; inv_resp_rgb: (256,3) f^-1(z) > 0 on lo..hi; mask: (H,W) bool."""
    log_dt = np.log(np.asarray(times))[:, None, None]
    devs = []
    for c in range(3):
        z = codes_rgb[..., c]
        valid = (z >= lo) & (z <= hi)
        with np.errstate(divide="ignore"):
            g = np.log(inv_resp_rgb[:, c].astype(np.float64))
        lnE = g[z] - log_dt
        lnE[~valid] = np.nan
        count = valid.sum(axis=0)
        keep = (count >= 2) & ~mask
        lnE = lnE[:, keep]
        med = np.nanmedian(lnE, axis=0)
        d = np.abs(lnE - med[None, :])
        devs.append(d[~np.isnan(d)])
    return float(np.median(np.concatenate(devs)))


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
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--lambda", dest="lam", type=float, default=10.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if not os.path.exists(a.list):
        print(f"data not found: {a.list}", file=sys.stderr)
        return 2
    entries = parse_list(a.list)
    times = np.array([t for _, t in entries], dtype=np.float32)
    bgr = [cv2.imread(p, cv2.IMREAD_COLOR) for p, _ in entries]
    codes = np.stack([im[..., ::-1] for im in bgr])  # RGB
    mask = np.any(np.all(codes == np.array([0, 0, 255], np.uint8), axis=-1), axis=0)

    # --- vfxgraph
    out = tempfile.mkdtemp(prefix="hdr_vs_opencv_")
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "vfxgraph-imaging",
                    "--example", "hdr_memorial"], cwd=ROOT, check=True)
    exe = os.path.join(ROOT, "target", "release", "examples", "hdr_memorial")
    res = subprocess.run([exe, a.list, out, str(a.samples), str(a.lam), str(a.runs)],
                         cwd=ROOT, check=True, capture_output=True, text=True)
    ours = json.loads(res.stdout.strip().splitlines()[-1])
    ours_resp = np.loadtxt(os.path.join(out, "response.csv"), delimiter=",")  # (256,3) RGB

    # --- OpenCV (BGR in, BGR response out)
    cal = cv2.createCalibrateDebevec()
    t_cal, resp_cv = best_of(a.runs, lambda: cal.process(bgr, times))
    merge = cv2.createMergeDebevec()
    t_merge, hdr_cv = best_of(a.runs, lambda: merge.process(bgr, times, resp_cv))
    cv_rgb = resp_cv.reshape(256, 3)[:, ::-1]
    rob = cv2.createCalibrateRobertson()
    t_rob, resp_rob = best_of(1, lambda: rob.process(bgr, times))
    rob_rgb = resp_rob.reshape(256, 3)[:, ::-1]
    gamma = np.repeat(((np.arange(256) / 255.0) ** 2.2)[:, None], 3, axis=1)

    errs = {
        "vfxgraph": consistency(codes, times, ours_resp, mask),
        "opencv_debevec": consistency(codes, times, cv_rgb, mask),
        "opencv_robertson": consistency(codes, times, rob_rgb, mask),
        "gamma_2.2": consistency(codes, times, gamma, mask),
    }
    ours_total = ours["calibrate_s"] + ours["merge_s"]
    cv_total = t_cal + t_merge
    report = {
        "images": f"{len(bgr)} x {bgr[0].shape[1]}x{bgr[0].shape[0]}",
        "masked_pixels": int(mask.sum()),
        "consistency_error": errs,
        "vfxgraph_s": {"calibrate": ours["calibrate_s"], "merge": ours["merge_s"],
                        "samples": ours["samples"], "lambda": ours["lambda"],
                        "rust_reported_consistency": ours["consistency"],
                        "monotonic": ours["monotonic"],
                        "unconstrained_consistency": ours["unconstrained_consistency"],
                        "unconstrained_monotonic": ours["unconstrained_monotonic"]},
        "opencv_s": {"calibrate": t_cal, "merge": t_merge, "robertson_calibrate": t_rob},
        "time_ratio_ours_over_opencv": ours_total / cv_total,
        "runs": a.runs,
    }
    if a.json:
        print(json.dumps(report, indent=1))
        return 0
    print(f"stack: {report['images']}, masked pixels {report['masked_pixels']}")
    print("exposure-consistency error (median |ln E_j - median_j ln E|, 32<=Z<=223):")
    for k, v in errs.items():
        print(f"  {k:18s} {v:.4f}")
    mono = lambda r: bool(np.all(np.diff(np.log(np.maximum(r, 1e-300)), axis=0) >= 0))
    print(f"monotonic on 0..255: vfxgraph {ours['monotonic']} (unconstrained solve: "
          f"{ours['unconstrained_monotonic']}, Rust-side consistency "
          f"{ours['unconstrained_consistency']:.4f}), OpenCV Debevec {mono(cv_rgb)}, "
          f"Robertson {mono(rob_rgb)}")
    print(f"vfxgraph (samples {ours['samples']}, lambda {ours['lambda']}): calibrate "
          f"{ours['calibrate_s']:.3f} s + merge {ours['merge_s']:.3f} s = {ours_total:.3f} s "
          f"(Rust-side consistency {ours['consistency']:.4f})")
    print(f"OpenCV Debevec: calibrate {t_cal:.3f} s + merge {t_merge:.3f} s = {cv_total:.3f} s")
    print(f"time ratio ours/OpenCV = {ours_total / cv_total:.3f}  (best of {a.runs}; noisy machine)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
