#!/usr/bin/env python3
"""Imports vfxgraph's PLY export with Blender's PLY importer (bpy); every vertex must match our
point (to float32 precision: Blender stores coordinates as 32-bit floats) and, when the export
has colours, every vertex colour must match ours exactly (8-bit sRGB).

usage: ply_check.py CLOUD.ply TRUTH.json
TRUTH.json: {"points": [[x, y, z], ...], "colors": [[r, g, b], ...] or null}
"""
import argparse
import json

import bpy

from _truth import fail


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("ply")
    ap.add_argument("truth")
    a = ap.parse_args()
    truth = json.load(open(a.truth))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.ply_import(filepath=a.ply)
    objs = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if len(objs) != 1:
        fail("expected one imported mesh, got %d" % len(objs))
    mesh = objs[0].data
    pts = truth["points"]
    if len(mesh.vertices) != len(pts):
        fail("%d vertices, expected %d" % (len(mesh.vertices), len(pts)))
    worst = 0.0
    for v, p in zip(mesh.vertices, pts):
        scale = max(1.0, max(abs(c) for c in p))
        d = max(abs(v.co[i] - p[i]) for i in range(3)) / scale
        worst = max(worst, d)
    if worst > 1e-6:
        fail("vertex positions differ by %g (relative)" % worst)
    colours = truth.get("colors")
    if colours:
        attr = mesh.color_attributes.active_color or (
            mesh.color_attributes[0] if len(mesh.color_attributes) else None)
        if attr is None:
            fail("no colour attribute imported")
        bad = 0
        for i, c in enumerate(colours):
            got = attr.data[i].color_srgb if hasattr(attr.data[i], "color_srgb") else attr.data[i].color
            rgb = [round(got[k] * 255) for k in range(3)]
            if rgb != list(c):
                bad += 1
        if bad:
            fail("%d of %d vertex colours differ" % (bad, len(colours)))
    print("bpy %s PLY import: %d vertices -> max relative position difference %.3g, colours %s"
          % (bpy.app.version_string, len(pts), worst, "exact" if colours else "none"))


if __name__ == "__main__":
    main()
