"""Shared by the client checks: our reprojections ("truth") and the comparison.

The truth file is written by vfxgraph's tests (crates/nodes/tests/export_clients.rs):

    {"width": W, "height": H, "fps": 24, "start_frame": 1,
     "frames": [{"frame": f, "target_frame": F, "pixels": [[u, v] | null, ...]}, ...]}

pixels[j] is where our camera of frame f (x ~ K(RX + t)) projects point j of the cloud, in our
convention: origin at the centre of the top-left pixel, x right, y down; null when the point is
behind the camera.
"""
import json
import math
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


class Comparison:
    """Collects pixel differences and prints one summary line."""

    def __init__(self, name, tol):
        self.name, self.tol = name, tol
        self.worst, self.count, self.where = 0.0, 0, None

    def add(self, ours, theirs, where):
        if ours is None:
            return
        d = math.hypot(theirs[0] - ours[0], theirs[1] - ours[1])
        if not math.isfinite(d):
            d = math.inf
        self.count += 1
        if d > self.worst:
            self.worst, self.where = d, where

    def finish(self):
        ok = self.count > 0 and self.worst <= self.tol
        print("%s: %d projections, max difference %.3e px (tolerance %.0e)%s -> %s"
              % (self.name, self.count, self.worst, self.tol,
                 "" if self.where is None else " at %s" % (self.where,), "OK" if ok else "FAIL"))
        return ok


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)
