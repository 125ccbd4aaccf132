"""Lens models on normalized coordinates, written out from their papers for the client checks
(independent of vfxgraph's Rust code): the distorted point q of the undistorted p.

- brown_conrady (OpenCV's k1 k2 k3 p1 p2, Brown 1966): r2 = |p|^2, rho = 1 + k1 r2 + k2 r2^2 +
  k3 r2^3; q = rho p + (2 p1 x y + p2 (r2 + 2 x^2), p1 (r2 + 2 y^2) + 2 p2 x y).
- division (Fitzgibbon 2001): p = q / (1 + k1 |q|^2 + k2 |q|^4); q from p by Newton's method on
  the radius.
"""
import math


def distort(model, params, x, y):
    if model in (None, "none"):
        return x, y
    if model == "brown_conrady":
        k1, k2, k3, p1, p2 = (params.get(n, 0.0) for n in ("k1", "k2", "k3", "p1", "p2"))
        r2 = x * x + y * y
        rho = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        return (rho * x + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                rho * y + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)
    if model == "division":
        k1, k2 = params.get("k1", 0.0), params.get("k2", 0.0)
        rp = math.hypot(x, y)
        if rp == 0:
            return x, y
        rq = rp
        for _ in range(50):
            if not abs(rq) < 1e6:
                return math.nan, math.nan
            s = 1 + k1 * rq * rq + k2 * rq ** 4
            g = rq / s - rp
            dg = (s - rq * (2 * k1 * rq + 4 * k2 * rq ** 3)) / (s * s)
            step = g / dg
            rq -= step
            if abs(step) < 1e-15 * (1 + rq):
                break
        return x * rq / rp, y * rq / rp
    raise ValueError("unknown lens model %r" % model)
