#!/usr/bin/env python3
"""Runs vfxgraph's Blender export in bpy; for every frame, Blender's camera (world matrix, and a
projection from its lens, sensor and shift, and Blender's own `calc_matrix_camera`) must project
the exported points to our reprojections within 0.01 px.

usage: blender_check.py SCRIPT.py TRUTH.json [--tol 0.01]
"""
import argparse
import math
import os
import runpy

import bpy
from mathutils import Vector

from _truth import Comparison, fail, load


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("script")
    ap.add_argument("truth")
    ap.add_argument("--tol", type=float, default=0.01)
    a = ap.parse_args()
    truth = load(a.truth)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    runpy.run_path(os.path.abspath(a.script), run_name="__main__")
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
    f1 = data.lens / data.sensor_width * W
    f2 = f1 / ycor
    cx = W / 2 - data.shift_x * W
    cy = H / 2 + data.shift_y * W / ycor
    for fr in truth["frames"]:
        scene.frame_set(fr["target_frame"])
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
    raise SystemExit(0 if ok else 1)


if __name__ == "__main__":
    main()
