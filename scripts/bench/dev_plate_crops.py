#!/usr/bin/env python3
"""Side-by-side crops around the mirror sphere on the Blender dev plate .

    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/dev_plate_crops.py FRAME OUT.png \
        truth.exr uniform.exr textured.exr ...

Each EXR is cropped to a square around the mirror sphere (projected with cameras_gt.json),
exposed ×4 and written sRGB, left to right in the order given. Reads/writes with bpy.
"""
import json, os, sys
import numpy as np
import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, '..', '..', '..', 'shared', 'data', 'blender_plate_dev')


def load(path):
    img = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    img.colorspace_settings.name = 'Non-Color'
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1, :, :3]


frame, out, paths = int(sys.argv[1]), sys.argv[2], sys.argv[3:]
cams = json.load(open(os.path.join(DATA, 'pinhole', 'cameras_gt.json')))
scene = json.load(open(os.path.join(DATA, 'scene.json')))
cam = [c for c in cams['frames'] if c['frame'] == frame][0]
K, R, t = np.array(cams['K']), np.array(cam['R']), np.array(cam['t'])
s = [x for x in scene['cg_spheres'] if x['name'] == 'sphere_mirror'][0]
x = K @ (R @ np.array(s['center']) + t)
cx, cy = x[0] / x[2], x[1] / x[2]
r = int(1.6 * K[0, 0] * s['radius'] / x[2])
crops = []
for p in paths:
    im = load(p)
    c = im[int(cy) - r:int(cy) + r, int(cx) - r:int(cx) + r] * 4.0
    c = np.clip(c, 0, 1)
    c = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    crops.append(c)
    crops.append(np.ones((2 * r, 4, 3)))
row = np.concatenate(crops[:-1], 1)
h, w, _ = row.shape
img = bpy.data.images.new('crops', w, h, alpha=True)
rgba = np.concatenate([row[::-1], np.ones((h, w, 1))], 2).astype(np.float32)
img.pixels.foreach_set(rgba.ravel())
img.filepath_raw = os.path.abspath(out)
img.file_format = 'PNG'
img.save()
