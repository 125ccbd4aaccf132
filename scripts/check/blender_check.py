#!/usr/bin/env python3
"""Runs vfxgraph's Blender export in bpy; for every frame, Blender's camera (world matrix, and a
projection from its lens, sensor and shift, and Blender's own `calc_matrix_camera`) must project
the exported points to our reprojections within 0.01 px.

usage: blender_check.py SCRIPT.py TRUTH.json [--tol 0.01] [--lens-tol 0.01]

With a lens (the truth's "lens" and "lens_grid": our undistorted pixel u of distorted pixels d),
the script's `tracking_camera(clip)` is applied to a movie clip of the plate's size and Blender's
own distortion is evaluated: its compositor's Movie Distortion node (Distort) warps a ramp image
whose red/green hold each pixel's own position, so the output at pixel d holds the source
position Blender's lens takes to d, which must be our u within --lens-tol px. The node's output
is translated by a whole number of pixels (bpy 5.0.1: 0 to 4 px in x and y depending on the
lens, also for a purely radial one; (1, -1) px with zero distortion; a pure translation): the
best whole-pixel translation in [-6, 6]² is found and reported, and everything else must agree
(a half-pixel or principal-point error would not be a whole-pixel translation and would show).
The scene camera renders the undistorted image: its projections are compared with the truth's
"pixels" (our pinhole projections when there is a lens).
"""
import argparse
import math
import os
import runpy

import bpy
import numpy as np
from mathutils import Vector

from _truth import Comparison, fail, load


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("script")
    ap.add_argument("truth")
    ap.add_argument("--tol", type=float, default=0.01)
    ap.add_argument("--lens-tol", type=float, default=0.01)
    a = ap.parse_args()
    truth = load(a.truth)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    namespace = runpy.run_path(os.path.abspath(a.script), run_name="__main__")
    scene = bpy.context.scene
    cam = bpy.data.objects.get("vfxgraph_camera")
    if cam is None or scene.camera != cam:
        fail("the script did not create the scene camera `vfxgraph_camera`")
    r = scene.render
    W, H = r.resolution_x, r.resolution_y
    if (W, H) != (truth["width"], truth["height"]):
        fail("render size %dx%d" % (W, H))
    fps = r.fps / r.fps_base
    if abs(fps - truth["fps"]) > 1e-6 * truth["fps"]:  # fps_base is a float32
        fail("fps %r, expected %r" % (fps, truth["fps"]))
    frames = [f["target_frame"] for f in truth["frames"]]
    if (scene.frame_start, scene.frame_end) != (min(frames), max(frames)):
        fail("frame range %d-%d" % (scene.frame_start, scene.frame_end))
    pts_obj = bpy.data.objects.get("vfxgraph_points")
    n = len(truth["frames"][0]["pixels"])
    if pts_obj is None or len(pts_obj.data.vertices) != n:
        fail("the point cloud object is missing or has the wrong number of vertices")
    world_pts = [pts_obj.matrix_world @ v.co for v in pts_obj.data.vertices]
    data = cam.data
    asp_x, asp_y = r.pixel_aspect_x, r.pixel_aspect_y
    print("bpy %s: lens %.6f mm, sensor %.3f mm (%s), shift %.6f %.6f, pixel aspect %g:%g, "
          "%d keys, %g fps" % (bpy.app.version_string, data.lens, data.sensor_width,
                               data.sensor_fit, data.shift_x, data.shift_y, asp_x, asp_y,
                               len(frames), fps))
    manual = Comparison("Blender camera (focal/sensor/shift)", a.tol)
    own = Comparison("Blender calc_matrix_camera", a.tol)
    # Blender's view plane with sensor fit HORIZONTAL (source: BKE_camera_params_compute_viewplane):
    # f1 = lens/sensor_width * W, ycor = aspect_y/aspect_x, f2 = f1/ycor, the window shifted by
    # shift * W pixels; converted to our pixels (origin at the first pixel's centre, y down).
    if data.sensor_fit != "HORIZONTAL":
        fail("sensor fit %s" % data.sensor_fit)
    ycor = asp_y / asp_x
    cx = W / 2 - data.shift_x * W
    cy = H / 2 + data.shift_y * W / ycor
    for fr in truth["frames"]:
        scene.frame_set(fr["target_frame"])
        # The lens at this frame (a zoom keyframes it).
        f1 = data.lens / data.sensor_width * W
        f2 = f1 / ycor
        depsgraph = bpy.context.evaluated_depsgraph_get()
        m = cam.matrix_world.copy()
        view = m.inverted()
        proj = cam.calc_matrix_camera(depsgraph, x=W, y=H, scale_x=asp_x, scale_y=asp_y)
        for j, ours in enumerate(fr["pixels"]):
            pc = view @ world_pts[j]
            if pc.z >= 0:
                continue
            xn, yn = pc.x / -pc.z, pc.y / -pc.z
            manual.add(ours, (f1 * xn + cx - 0.5, -f2 * yn + cy - 0.5), (fr["frame"], j))
            clip = proj @ Vector((pc.x, pc.y, pc.z, 1.0))
            nx, ny = clip.x / clip.w, clip.y / clip.w
            own.add(ours, ((nx + 1) / 2 * W - 0.5, (1 - ny) / 2 * H - 0.5), (fr["frame"], j))
    if truth.get("plate"):
        bgs = data.background_images
        if len(bgs) != 1 or bgs[0].image is None or bgs[0].image.source != "SEQUENCE":
            fail("no background image sequence")
        print("background:", bgs[0].image.filepath)
    ok = manual.finish() & own.finish()
    if truth.get("lens"):
        ok &= check_lens(namespace, truth, a.lens_tol, os.path.dirname(os.path.abspath(a.truth)))
    elif namespace.get("DISTORTION") is not None:
        fail("the script has a lens but the truth has none")
    raise SystemExit(0 if ok else 1)


def check_lens(namespace, truth, tol, work):
    """Blender's distortion (Movie Distortion node, the script's tracking camera) against ours."""
    W, H = truth["width"], truth["height"]
    lens = namespace.get("DISTORTION")
    if lens is None:
        fail("the truth has a %s lens but the script's DISTORTION is None" % truth["lens"]["model"])
    scene = bpy.context.scene
    ramp = bpy.data.images.new("vfxgraph_ramp", W, H, float_buffer=True, alpha=True)
    ramp.colorspace_settings.name = "Non-Color"
    xs, ys = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    px = np.zeros((H, W, 4), np.float32)
    # Blender's rows go up from the bottom: buffer row i is our row H-1-i.
    px[..., 0], px[..., 1], px[..., 3] = xs, (H - 1) - ys, 1.0
    ramp.pixels.foreach_set(px.ravel())
    ramp_path = os.path.join(work, "vfxgraph_ramp.exr")
    ramp.filepath_raw, ramp.file_format = ramp_path, "OPEN_EXR"
    ramp.save()
    clip = bpy.data.movieclips.load(ramp_path)
    if tuple(clip.size) != (W, H):
        fail("the ramp clip is %s" % (tuple(clip.size),))
    namespace["tracking_camera"](clip)
    cam = clip.tracking.camera
    print("tracking camera: %s, focal %.6f px, principal point %s px, k %s, p %s (ours: %s%s)"
          % (cam.distortion_model, cam.focal_length_pixels, tuple(cam.principal_point_pixels),
             (cam.brown_k1, cam.brown_k2, cam.brown_k3, cam.brown_k4),
             (cam.brown_p1, cam.brown_p2), lens["ours"],
             "" if lens["fit_error_px"] is None else
             ", refitted within %.3e px" % lens["fit_error_px"]))
    tree = bpy.data.node_groups.new("vfxgraph_lens_check", "CompositorNodeTree")
    scene.compositing_node_group = tree
    n_img = tree.nodes.new("CompositorNodeImage")
    n_img.image = ramp
    n_dist = tree.nodes.new("CompositorNodeMovieDistortion")
    n_dist.clip = clip
    n_dist.inputs["Type"].default_value = "Distort"
    out = tree.nodes.new("NodeGroupOutput")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    tree.links.new(n_img.outputs[0], n_dist.inputs[0])
    tree.links.new(n_dist.outputs[0], out.inputs[0])
    r = scene.render
    saved = (r.resolution_x, r.resolution_y, r.pixel_aspect_x, r.pixel_aspect_y)
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.image_settings.file_format, r.image_settings.color_depth = "OPEN_EXR", "32"
    r.filepath = os.path.join(work, "vfxgraph_distorted.exr")
    scene.camera = None  # the compositor alone: no scene render
    bpy.ops.render.render(write_still=True)
    r.resolution_x, r.resolution_y, r.pixel_aspect_x, r.pixel_aspect_y = saved
    res = bpy.data.images.load(r.filepath)
    res.colorspace_settings.name = "Non-Color"
    got = np.array(res.pixels[:], np.float64).reshape(H, W, 4)[::-1]  # rows from the top
    grid = np.asarray(truth["lens_grid"], np.float64)  # d.x d.y u.x u.y
    d = grid[:, :2].astype(int)
    best = None
    for sx in range(-6, 7):
        for sy in range(-6, 7):
            cx, cy = d[:, 0] - sx, d[:, 1] - sy
            inside = (cx >= 0) & (cx < W) & (cy >= 0) & (cy < H)
            if inside.sum() < 0.9 * len(d):
                continue
            v = got[cy[inside], cx[inside], :2]
            e = np.hypot(*(v - grid[inside, 2:]).T)
            if best is None or e.max() < best[0]:
                best = (e.max(), sx, sy, int(inside.sum()), float(np.median(e)))
    if best is None:
        fail("no translation of the node's output covers the grid")
    worst, sx, sy, n, med = best
    ok = worst <= tol
    print("Blender Movie Distortion vs ours: %d grid pixels, max difference %.3e px, median %.1e "
          "(tolerance %.0e), output translated by (%d, %d) px -> %s"
          % (n, worst, med, tol, sx, sy, "OK" if ok else "FAIL"))
    return ok


if __name__ == "__main__":
    main()
