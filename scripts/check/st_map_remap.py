#!/usr/bin/env python3
"""Applies our ST-map with OpenCV's `remap` and compares the result with our `undistort`.

    st_map_remap.py PLATE.pfm ST_MAP.pfm OURS.pfm [--tolerance 0.005]

PLATE is the source image, ST_MAP the map vfxgraph's `write_st_map` wrote (Nuke's STMap
convention: red = s, green = t, the source position normalized 0-1, origin bottom-left; -1 where
there is no source), OURS vfxgraph's `undistort` of PLATE. OpenCV's coordinates have the origin
at the top-left pixel's centre, so map_x = s * W - 0.5 and map_y = (1 - t) * H - 0.5 with W x H
the source's size. Positions outside the source's pixel edges are black in ours; OpenCV's
bilinear `remap` with a replicated border is masked the same way (inside the edges both clamp to
the outer pixels). Prints the largest and RMS difference relative to the range of OURS and exits
1 when the largest exceeds the tolerance (a fraction of that range).

The files are float PFM (lossless f32, read by OpenCV's own PFM codec): the pip wheels of
OpenCV are built without OpenEXR, so the test writes the ST-map EXR as `write_st_map` does, reads
it back and hands the same f32 values over as PFM. Needs opencv-python(-headless) and numpy
(the venv ~/.cache/vfxgraph/pyenv-cv).
"""
import argparse
import os
import sys

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import cv2  # noqa: E402
import numpy as np  # noqa: E402


def read(path):
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit("FAIL cannot read %s with OpenCV %s" % (path, cv2.__version__))
    return img.astype(np.float32)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("plate")
    ap.add_argument("st_map")
    ap.add_argument("ours")
    ap.add_argument("--tolerance", type=float, default=0.005)
    a = ap.parse_args()
    plate, st, ours = read(a.plate), read(a.st_map), read(a.ours)
    h, w = plate.shape[:2]
    # OpenCV reads colour channels as BGR: red (s) is the last one, green (t) the middle.
    s, t = st[..., 2], st[..., 1]
    if st.shape[:2] != ours.shape[:2]:
        sys.exit("FAIL the map is %s but ours is %s" % (st.shape[:2], ours.shape[:2]))
    map_x = (s * w - 0.5).astype(np.float32)
    map_y = ((1.0 - t) * h - 0.5).astype(np.float32)
    theirs = cv2.remap(plate, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    inside = (s >= 0) & (t >= 0) & (map_x >= -0.5) & (map_x <= w - 0.5) & (map_y >= -0.5) & (map_y <= h - 0.5)
    theirs[~inside] = 0.0
    lo, hi = float(ours.min()), float(ours.max())
    rng = hi - lo
    if not rng > 0:
        sys.exit("FAIL our undistorted image is constant")
    d = np.abs(theirs - ours)
    worst, rms = float(d.max()) / rng, float(np.sqrt(np.mean(d * d))) / rng
    p999 = float(np.quantile(d, 0.999)) / rng
    print(
        "OpenCV %s remap of the ST-map -> ours: max %.4f %%, 99.9th percentile %.4f %%, RMS %.5f %% "
        "of the range %.4g (%dx%d, %d pixels inside)"
        % (cv2.__version__, 100 * worst, 100 * p999, 100 * rms, rng, w, h, int(inside.sum()))
    )
    if worst > a.tolerance:
        print("FAIL max difference %.4f %% > %.4f %%" % (100 * worst, 100 * a.tolerance))
        sys.exit(1)


if __name__ == "__main__":
    main()
