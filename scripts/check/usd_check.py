#!/usr/bin/env python3
"""Opens vfxgraph's USD export with usd-core; for every time sample, the camera's world
transform and frustum (GfCamera from UsdGeom.Camera) must project the stage's points to our
reprojections within 0.01 px.

usage: usd_check.py STAGE.usda TRUTH.json [--tol 0.01]

The frustum's window maps to normalized device coordinates [-1, 1]; pixel = (ndc + 1)/2 · W − ½
(x), (1 − ndc)/2 · H − ½ (y, down), with W×H the plate size from the truth file. When the truth
has a lens ("lens": our distortion JSON), the camera prim must carry it as the documented
`vfxgraph:lens:*` attributes, and the frustum's (undistorted) pixel is taken through the model
those attributes name (scripts/check/_lens.py, written from the papers) before the comparison:
pixel = (cx, cy) + (f1, f2) * d(((u + ½) − cx) / f1, ((v + ½) − cy) / f2) − ½.
"""
import argparse

from pxr import Gf, Usd, UsdGeom

from _lens import distort
from _truth import Comparison, fail, load


def lens_of(prim, truth):
    """The lens read from the camera prim's vfxgraph:lens:* attributes (None for a pinhole)."""
    model = prim.GetAttribute("vfxgraph:lens:model")
    want = truth.get("lens")
    if not model or not model.HasAuthoredValue():
        if want:
            fail("the truth has a %s lens but the camera has no vfxgraph:lens:model" % want["model"])
        return None
    name = model.Get()
    if not want or want["model"] != name:
        fail("the camera's lens model is %r, expected %r" % (name, want and want["model"]))
    names = {"brown_conrady": ("k1", "k2", "k3", "p1", "p2"), "division": ("k1", "k2")}[name]
    params = {n: prim.GetAttribute("vfxgraph:lens:" + n).Get() for n in names}
    for n in names:
        if params[n] is None or params[n] != want.get(n, 0.0):
            fail("vfxgraph:lens:%s = %r, expected %r" % (n, params[n], want.get(n, 0.0)))
    f = prim.GetAttribute("vfxgraph:lens:focalPixels").Get()
    c = prim.GetAttribute("vfxgraph:lens:principalPointPixels").Get()
    size = prim.GetAttribute("vfxgraph:lens:imageSize").Get()
    if f is None or c is None or size is None or tuple(size) != (truth["width"], truth["height"]):
        fail("vfxgraph:lens:focalPixels/principalPointPixels/imageSize missing or wrong: %s %s %s"
             % (f, c, size))
    print("lens: %s %s, focal %s px, principal point %s px" % (name, params, tuple(f), tuple(c)))
    return name, params, tuple(f), tuple(c)


def through_lens(lens, u, v):
    if lens is None:
        return u, v
    name, params, f, c = lens
    x, y = distort(name, params, (u + 0.5 - c[0]) / f[0], (v + 0.5 - c[1]) / f[1])
    return c[0] + f[0] * x - 0.5, c[1] + f[1] * y - 0.5


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
    lens = lens_of(cam_prim, truth)
    st = cam_prim.GetAttribute("vfxgraph:lens:stMap")
    if truth.get("st_map"):
        if not st or st.Get() is None or st.Get().path != truth["st_map"]:
            fail("vfxgraph:lens:stMap is %r, expected %r" % (st and st.Get(), truth["st_map"]))
        print("ST-map: %s (resolves to %s)" % (st.Get().path, st.Get().resolvedPath or "-"))
    cache = UsdGeom.XformCache()
    print("usd-core %s: %d time samples, focal %.6f, aperture %.6f x %.6f, offsets %.6f %.6f, "
          "metersPerUnit %g" % (".".join(map(str, Usd.GetVersion())), len(samples),
                                usd_cam.GetFocalLengthAttr().Get(),
                                usd_cam.GetHorizontalApertureAttr().Get(),
                                usd_cam.GetVerticalApertureAttr().Get(),
                                usd_cam.GetHorizontalApertureOffsetAttr().Get(),
                                usd_cam.GetVerticalApertureOffsetAttr().Get(),
                                UsdGeom.GetStageMetersPerUnit(stage)))
    cmp = Comparison("USD camera frustum" + (" through vfxgraph:lens" if lens else ""), a.tol)
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
            if ours is None:  # behind the camera, or (with a lens) outside the frame
                continue
            u, v = through_lens(lens, (nx + 1) / 2 * W - 0.5, (1 - ny) / 2 * H - 0.5)
            cmp.add(ours, (u, v), (fr["frame"], j))
    raise SystemExit(0 if cmp.finish() else 1)


if __name__ == "__main__":
    main()
