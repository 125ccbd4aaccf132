#!/usr/bin/env python3
"""pycolmap reads vfxgraph's COLMAP export; projecting its points with its cameras must land on
our reprojections within 1e-6 px; with --obs-tol, every 2-D point linked to a point must lie
within that distance of the point's projection.

usage: colmap_check.py MODEL_DIR TRUTH.json [--tol 1e-6] [--obs-tol PX]

COLMAP's pixel origin is the top-left corner of the image, ours the centre of the top-left
pixel: COLMAP's pixel − 0.5 is compared with ours.
"""
import argparse

import numpy as np
import pycolmap

from _truth import Comparison, fail, load


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("truth")
    ap.add_argument("--tol", type=float, default=1e-6)
    ap.add_argument("--obs-tol", type=float, default=None,
                    help="also require every linked 2-D point within this distance (px) of its "
                         "point's projection (the solve's final inlier threshold, or a "
                         "bound for observations known to be exact)")
    a = ap.parse_args()
    truth = load(a.truth)
    rec = pycolmap.Reconstruction(a.model)
    print("pycolmap %s: %s" % (pycolmap.__version__, rec.summary().replace("\n", "; ")))
    if rec.num_images() != len(truth["frames"]):
        fail("%d images, expected %d" % (rec.num_images(), len(truth["frames"])))
    n_points = len(truth["frames"][0]["pixels"]) if truth["frames"] else 0
    if rec.num_points3D() != n_points:
        fail("%d points, expected %d" % (rec.num_points3D(), n_points))
    for cam in rec.cameras.values():
        if (cam.width, cam.height) != (truth["width"], truth["height"]):
            fail("camera %d is %dx%d" % (cam.camera_id, cam.width, cam.height))
    cmp = Comparison("pycolmap projections", a.tol)
    for fr, image_id in zip(truth["frames"], sorted(rec.images.keys())):
        img = rec.images[image_id]
        cam = rec.cameras[img.camera_id]
        pose = img.cam_from_world()
        for j, ours in enumerate(fr["pixels"]):
            xyz = rec.points3D[j + 1].xyz
            xc = pose * xyz
            if xc[2] <= 0:
                continue
            uv = cam.img_from_cam(np.asarray(xc, dtype=float))
            cmp.add(ours, (uv[0] - 0.5, uv[1] - 0.5), (fr["frame"], j))
            # COLMAP's own projection helper agrees.
            p = img.project_point(xyz)
            if p is not None:
                cmp.add(ours, (p[0] - 0.5, p[1] - 0.5), (fr["frame"], j, "project_point"))
    # Tracks: every observation of a point is listed both ways; with --obs-tol, each lies that
    # close to where its point projects (a real solve's observations have real residuals).
    n_obs, worst_obs = 0, 0.0
    for pid, p in rec.points3D.items():
        for el in p.track.elements:
            img = rec.images[el.image_id]
            uv = img.project_point(p.xyz)
            xy = img.points2D[el.point2D_idx].xy
            worst_obs = max(worst_obs, float(np.hypot(*(np.asarray(uv) - xy))))
            n_obs += 1
    unassigned = sum(1 for img in rec.images.values() for p in img.points2D
                     if not p.has_point3D())
    print("2-D points: %d linked, %d unassigned (POINT3D_ID -1); pycolmap's mean reprojection "
          "error %.3f px -> reported" % (n_obs, unassigned, rec.compute_mean_reprojection_error()))
    if a.obs_tol is None:
        print("tracks: %d observations, max distance to the projection %.3e px (not checked)"
              % (n_obs, worst_obs))
    else:
        print("tracks: %d observations, max distance to the projection %.9f px (bound %.9f) -> %s"
              % (n_obs, worst_obs, a.obs_tol, "OK" if worst_obs <= a.obs_tol else "FAIL"))
        if worst_obs > a.obs_tol:
            fail("an observation is %.3e px from its point's projection" % worst_obs)
    for pid, p in rec.points3D.items():
        for el in p.track.elements:
            img = rec.images[el.image_id]
            if img.points2D[el.point2D_idx].point3D_id != pid:
                fail("point %d: track element (%d, %d) does not point back"
                     % (pid, el.image_id, el.point2D_idx))
    raise SystemExit(0 if cmp.finish() else 1)


if __name__ == "__main__":
    main()
