#!/usr/bin/env python3
"""Where the placement puts the CG spheres of the Blender dev plate, in pixels.

    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/dev_plate_placement.py \
        VARIANT CORNERS.json [CAMERAS.json] [frames…]

VARIANT is `pinhole` or `distorted` (../shared/data/blender_plate_dev/VARIANT). CORNERS.json is a
`point_cloud_calibrate` report of the four ground marks (its `points`, in marks.txt's order: the
scene's (±0.6, ±0.6, 0)); CAMERAS.json the cameras they were measured with — a `write_cameras`
JSON (with `intrinsics`) or an `export_cameras` json (per frame K) — or the truth's own when left
out. The similarity (Umeyama) that maps the four true mark positions onto the measured ones moves
each sphere centre of scene.json as `place_scene` does; the script projects it with CAMERAS (and
their lens) and the true centre with the true cameras and lens, and prints the difference per
frame (default 24 and 47): how far from the truth the composite draws the sphere, whatever
the marks' and the cameras' errors. Needs numpy (the export venv's python, as the other
bench scripts).
"""
import json, os, sys

import numpy as np

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', 'shared', 'data',
                    'blender_plate_dev')
MARKS = [(-0.6, -0.6, 0.0), (0.6, -0.6, 0.0), (0.6, 0.6, 0.0), (-0.6, 0.6, 0.0)]


def umeyama(src, dst):
    """The similarity (scale c, rotation r, translation t) with dst ≈ c r src + t, least squares."""
    src, dst = np.asarray(src, float), np.asarray(dst, float)
    ms, md = src.mean(0), dst.mean(0)
    u, sv, vt = np.linalg.svd((dst - md).T @ (src - ms) / len(src))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    r = u @ d @ vt
    c = np.trace(np.diag(sv) @ d) / ((src - ms) ** 2).sum(1).mean()
    return c, r, md - c * r @ ms


def project(k, lens, r, t, x):
    p = np.asarray(r, float) @ np.asarray(x, float) + np.asarray(t, float)
    u, v = p[0] / p[2], p[1] / p[2]
    if lens and lens.get('model', 'brown_conrady') not in ('none',):
        k1, k2, p1, p2 = (lens.get(n, 0.0) for n in ('k1', 'k2', 'p1', 'p2'))
        r2 = u * u + v * v
        rho = 1 + k1 * r2 + k2 * r2 * r2
        u, v = u * rho + 2 * p1 * u * v + p2 * (r2 + 2 * u * u), v * rho + p1 * (r2 + 2 * v * v) + 2 * p2 * u * v
    return k[0][0] * u + k[0][1] * v + k[0][2], k[1][1] * v + k[1][2]


def main():
    a = sys.argv[1:]
    if len(a) < 2 or a[0] not in ('pinhole', 'distorted'):
        sys.exit(__doc__)
    variant, corners = a[0], a[1]
    rest = a[2:]
    cams_path = rest.pop(0) if rest and not rest[0].isdigit() else None
    frames = [int(f) for f in rest] or [24, 47]
    truth = json.load(open(os.path.join(DATA, variant, 'cameras_gt.json')))
    scene = json.load(open(os.path.join(DATA, 'scene.json')))
    cams = json.load(open(cams_path)) if cams_path else None
    pts = json.load(open(corners))['points']
    c, r, t = umeyama(MARKS, pts)
    for f in frames:
        tf = next(x for x in truth['frames'] if x['frame'] == f)
        if cams is None:
            k, lens, cf = truth['K'], truth.get('distortion'), tf
        else:
            cf = next(x for x in cams['frames'] if x['frame'] == f)
            intr = cams.get('intrinsics') or {}
            k = cf.get('K') or intr['K']
            lens = cams.get('distortion') or intr.get('distortion')
        for s in scene['cg_spheres']:
            x = c * r @ np.asarray(s['center'], float) + t
            ours = project(k, lens, cf['R'], cf['t'], x)
            want = project(truth['K'], truth.get('distortion'), tf['R'], tf['t'], s['center'])
            print('frame %d %-16s placed %+.2f %+.2f px (x right, y down) from the truth' % (
                f, s['name'], ours[0] - want[0], ours[1] - want[1]))


main()
