#!/usr/bin/env python3
"""Opens vfxgraph's USD export with usd-core; for every time sample, the camera's world
transform and frustum (GfCamera from UsdGeom.Camera) must project the stage's points to our
reprojections within 0.01 px.

usage: usd_check.py STAGE.usda TRUTH.json [--tol 0.01]

The frustum's window maps to normalized device coordinates [-1, 1]; pixel = (ndc + 1)/2 · W − ½
(x), (1 − ndc)/2 · H − ½ (y, down), with W×H the plate size from the truth file.
"""
import argparse

from pxr import Gf, Usd, UsdGeom

from _truth import Comparison, fail, load


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("stage")
    ap.add_argument("truth")
    ap.add_argument("--tol", type=float, default=0.01)
    a = ap.parse_args()
    truth = load(a.truth)
    stage = Usd.Stage.Open(a.stage)
    if stage is None:
        fail("the stage does not open")
    cam_prim = stage.GetPrimAtPath("/World/camera")
    if not cam_prim or not cam_prim.IsA(UsdGeom.Camera):
        fail("no UsdGeom.Camera at /World/camera")
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.y:
        fail("up axis %s" % UsdGeom.GetStageUpAxis(stage))
    if abs(stage.GetTimeCodesPerSecond() - truth["fps"]) > 1e-9:
        fail("timeCodesPerSecond %r" % stage.GetTimeCodesPerSecond())
    usd_cam = UsdGeom.Camera(cam_prim)
    xf = UsdGeom.Xformable(cam_prim)
    samples = xf.GetTimeSamples()
    want = [f["target_frame"] for f in truth["frames"]]
    if [int(s) for s in samples] != want:
        fail("time samples %s, expected %s" % (samples[:5], want[:5]))
    pts_prim = UsdGeom.Points(stage.GetPrimAtPath("/World/points"))
    if not pts_prim:
        fail("no UsdGeom.Points at /World/points")
    W, H = truth["width"], truth["height"]
    cache = UsdGeom.XformCache()
    print("usd-core %s: %d time samples, focal %.6f, aperture %.6f x %.6f, offsets %.6f %.6f, "
          "metersPerUnit %g" % (".".join(map(str, Usd.GetVersion())), len(samples),
                                usd_cam.GetFocalLengthAttr().Get(),
                                usd_cam.GetHorizontalApertureAttr().Get(),
                                usd_cam.GetVerticalApertureAttr().Get(),
                                usd_cam.GetHorizontalApertureOffsetAttr().Get(),
                                usd_cam.GetVerticalApertureOffsetAttr().Get(),
                                UsdGeom.GetStageMetersPerUnit(stage)))
    cmp = Comparison("USD camera frustum", a.tol)
    for fr in truth["frames"]:
        t = Usd.TimeCode(fr["target_frame"])
        cache.SetTime(t)
        gf = usd_cam.GetCamera(t)
        frustum = gf.frustum
        view = frustum.ComputeViewMatrix()
        proj = frustum.ComputeProjectionMatrix()
        world = cache.GetLocalToWorldTransform(pts_prim.GetPrim())
        pts = pts_prim.GetPointsAttr().Get(t)
        if len(pts) != len(fr["pixels"]):
            fail("%d points, expected %d" % (len(pts), len(fr["pixels"])))
        for j, ours in enumerate(fr["pixels"]):
            pw = world.Transform(Gf.Vec3d(pts[j]))
            pc = view.Transform(pw)
            if pc[2] >= 0:
                continue
            clip = Gf.Vec4d(pc[0], pc[1], pc[2], 1.0) * proj
            nx, ny = clip[0] / clip[3], clip[1] / clip[3]
            cmp.add(ours, ((nx + 1) / 2 * W - 0.5, (1 - ny) / 2 * H - 0.5), (fr["frame"], j))
    raise SystemExit(0 if cmp.finish() else 1)


if __name__ == "__main__":
    main()
