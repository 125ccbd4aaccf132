#!/usr/bin/env python3
"""Error of a composite on the Blender dev plate against its truth frames, per region.

    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/dev_plate_regions.py \
        'graphs/out/dev_plate_shot/composite.%04d.exr' 0 24 47 [--json out.json] \
        [--variant pinhole|distorted]

`--variant distorted` measures a composite over the distorted plate (graphs/dev_plate_lens_shot.yaml)
against distorted/truth: the regions' pixel rays go through the undistorted point of each pixel
(cameras_gt.json's Brown–Conrady lens inverted by Newton's method).

Regions, from the exact cameras (cameras_gt.json) and scene.json: `diffuse` and `mirror` = pixels
whose ray passes within 0.85 r of the sphere's centre (the silhouette less its anti-aliased rim);
`shadow` = ground pixels (no sphere hit) whose ground point lies within 2.5 r of the sphere's
contact point; `mirror_floor`/`mirror_up` = mirror pixels whose reflected ray goes down (the floor's
reflection) / up (dome and boxes); `mirror_box` = mirror pixels whose reflected ray meets one of the
set's boxes (exact, from scene.json's corners), split per box as `mirror_<box name>` (the nearest
box the reflected ray meets), `mirror_ground` = `mirror_floor` less those; `far` = ground pixels 0.8–2 m from both spheres and off the boxes' footprints.
Figures per region on 4×4-pixel block means (blocks wholly inside the region; a pixel's σ at 32
spp is ~80 % of its mean, too much to see a bias), relative to the truth's mean there (channel
mean): `bias` = mean(comp − truth), `rms` = RMS over blocks of (comp − truth), `truth_noise` =
the truth's own Monte Carlo σ of a block. The truth's σ in `far` is RMS(plate_linear − truth)/√2
(two independent 32-spp renders of the same pixels, the objects changing nothing there);
elsewhere it is the residual (block − mean of its 4 neighbour blocks, which removes linear
shading) scaled by the ratio of the two estimates in `far`. `rms/σ` ≈ 1.4 for an unbiased
composite as noisy as the truth. Reads EXRs with bpy.
"""
import json, sys, os
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
    return a.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)  # row 0 = top


def undistort(q, lens):
    """Undistorted normalized points of the distorted ones q (N×2), OpenCV's Brown–Conrady."""
    k1, k2, p1, p2 = (lens.get(k, 0.0) for k in ('k1', 'k2', 'p1', 'p2'))
    p = q.copy()
    for _ in range(30):
        x, y = p[:, 0], p[:, 1]
        r2 = x * x + y * y
        rho = 1 + k1 * r2 + k2 * r2 * r2
        drho = k1 + 2 * k2 * r2
        f = np.stack([x * rho + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - q[:, 0],
                      y * rho + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - q[:, 1]], 1)
        a = rho + 2 * x * x * drho + 2 * p1 * y + 6 * p2 * x
        b = 2 * x * y * drho + 2 * p1 * x + 2 * p2 * y
        d = rho + 2 * y * y * drho + 6 * p1 * y + 2 * p2 * x
        det = a * d - b * b
        p = p - np.stack([(d * f[:, 0] - b * f[:, 1]) / det, (a * f[:, 1] - b * f[:, 0]) / det], 1)
    return p


def masks(cam, K, w, h, scene, lens=None):
    R = np.array(cam['R']); C = np.array(cam['C'])
    ys, xs = np.mgrid[0:h, 0:w]
    pix = np.stack([xs, ys, np.ones_like(xs)], -1).reshape(-1, 3).astype(float)
    n = (np.linalg.inv(K) @ pix.T).T
    if lens:
        n[:, :2] = undistort(n[:, :2], lens)
    d = (R.T @ n.T).T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = {}
    hit_any = np.zeros(len(d), bool)
    spheres = {s['name']: s for s in scene['cg_spheres']}
    for key, name in (('diffuse', 'sphere_diffuse'), ('mirror', 'sphere_mirror')):
        s = spheres[name]; c = np.array(s['center']); r = s['radius']
        t = (c - C) @ d.T
        closest = np.linalg.norm(C + t[:, None] * d - c, axis=1)
        out[key] = (closest < 0.85 * r) & (t > 0)
        if key == 'mirror':
            th = t - np.sqrt(np.maximum(r * r - closest ** 2, 0))
            n = (C + th[:, None] * d - c) / r
            refl = d - 2 * np.sum(d * n, 1, keepdims=True) * n
            out['mirror_floor'] = out[key] & (refl[:, 2] < -0.05)
            out['mirror_up'] = out[key] & (refl[:, 2] > 0.05)
            # the mirror's pixels whose reflected ray meets a box (scene.json's, exact)
            hb = np.zeros(len(d), bool)
            p = C + th[:, None] * d
            nearest = np.full(len(d), np.inf)
            which = np.full(len(d), -1)
            for bi, b in enumerate(scene['boxes']):
                cs = np.array(b['corners']); e1 = cs[1] - cs[0]; e2 = cs[3] - cs[0]
                l1, l2 = np.linalg.norm(e1), np.linalg.norm(e2); u1, u2 = e1 / l1, e2 / l2
                po = p - cs[0]
                lo = np.stack([po @ u1, po @ u2, po[:, 2]], -1)
                ld = np.stack([refl @ u1, refl @ u2, refl[:, 2]], -1)
                with np.errstate(divide='ignore', invalid='ignore'):
                    t1 = -lo / ld; t2 = (np.array([l1, l2, cs[4, 2]]) - lo) / ld
                tn = np.nanmax(np.minimum(t1, t2), 1); tf = np.nanmin(np.maximum(t1, t2), 1)
                hit = (tf >= np.maximum(tn, 0))
                hb |= hit
                closer = hit & (np.maximum(tn, 0) < nearest)
                nearest[closer] = np.maximum(tn, 0)[closer]
                which[closer] = bi
            out['mirror_box'] = out[key] & hb
            # per box (the nearest one the reflected ray meets): which proxy a bias comes from
            for bi, b in enumerate(scene['boxes']):
                out['mirror_' + b['name']] = out[key] & (which == bi)
            out['mirror_ground'] = out['mirror_floor'] & ~hb
        hit_any |= (closest < 1.05 * r) & (t > 0)
    tg = -C[2] / d[:, 2]
    g = C + tg[:, None] * d
    ground = (tg > 0) & ~hit_any
    # box footprints (with a margin) and the boxes' image (rays through any box's bounding volume)
    onbox = np.zeros(len(d), bool)
    for b in scene['boxes']:
        cs = np.array(b['corners'])
        lo, hi = cs.min(0) - 0.05, cs.max(0) + 0.05
        # slab test against the box's axis-aligned bound
        with np.errstate(divide='ignore', invalid='ignore'):
            t1 = (lo - C) / d; t2 = (hi - C) / d
        tn = np.nanmax(np.minimum(t1, t2), 1); tf = np.nanmin(np.maximum(t1, t2), 1)
        onbox |= (tn <= tf) & (tf > 0)
    ground &= ~onbox
    dist = []
    for key, name in (('diffuse', 'sphere_diffuse'), ('mirror', 'sphere_mirror')):
        s = spheres[name]; c = np.array(s['center'])
        dd = np.linalg.norm(g[:, :2] - c[:2], axis=1)
        dist.append(dd)
        out[key + '_shadow'] = ground & (dd < 2.5 * s['radius'])
    out['far'] = ground & (np.minimum(*dist) > 0.8) & (np.abs(g[:, 0]) < 2) & (np.abs(g[:, 1]) < 2)
    return {k: v.reshape(h, w) for k, v in out.items()}


B = 4  # block size: per-pixel σ at 32 spp is ~80 % of the mean, so compare 4×4 block means


def blocks(img, mask):
    h, w = mask.shape
    h4, w4 = h // B * B, w // B * B
    im = img[:h4, :w4].reshape(h4 // B, B, w4 // B, B, -1).mean((1, 3))
    mk = mask[:h4, :w4].reshape(h4 // B, B, w4 // B, B).all((1, 3))
    return im, mk


def residual(img):
    p = np.pad(img, ((1, 1), (1, 1), (0, 0)), mode='edge')
    m = (p[:-2, 1:-1] + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:]) / 4
    return img - m


def main():
    args = [a for a in sys.argv[1:]]
    jpath = None
    if '--json' in args:
        i = args.index('--json'); jpath = args[i + 1]; del args[i:i + 2]
    variant = 'pinhole'
    if '--variant' in args:
        i = args.index('--variant'); variant = args[i + 1]; del args[i:i + 2]
    assert variant in ('pinhole', 'distorted'), variant
    pattern, frames = args[0], [int(f) for f in args[1:]]
    cams = json.load(open(os.path.join(DATA, variant, 'cameras_gt.json')))
    scene = json.load(open(os.path.join(DATA, 'scene.json')))
    K = np.array(cams['K'])
    rows = []
    for f in frames:
        truth = load(os.path.join(DATA, variant, 'truth', 'frame.%04d.exr' % f))
        plate = load(os.path.join(DATA, variant, 'plate_linear', 'frame.%04d.exr' % f))
        comp = load(pattern % f)
        h, w, _ = truth.shape
        cam = [c for c in cams['frames'] if c['frame'] == f][0]
        m = masks(cam, K, w, h, scene, cams.get('distortion'))
        tb, far = blocks(truth, m['far'])
        pb, _ = blocks(plate, m['far'])
        sig_far = np.sqrt(np.mean((pb[far] - tb[far]) ** 2) / 2)
        res = residual(tb)
        k = sig_far / np.sqrt(np.mean(res[far] ** 2))
        cb, _ = blocks(comp, m['far'])
        row = {'frame': f, 'far_sigma_scale': k}
        for key in ('diffuse', 'mirror', 'mirror_floor', 'mirror_ground', 'mirror_box',
                    *['mirror_' + b['name'] for b in scene['boxes']], 'mirror_up',
                    'diffuse_shadow', 'mirror_shadow', 'far'):
            _, sel = blocks(truth, m[key])
            n = int(sel.sum())
            if n < (3 if key.startswith('mirror_box_') else 10):
                continue
            mt = tb[sel].mean()
            e = cb[sel] - tb[sel]
            sig = sig_far if key == 'far' else k * np.sqrt(np.mean(res[sel] ** 2))
            row[key] = {'pixels': n, 'truth_mean': mt, 'bias': e.mean() / mt,
                        'rms': np.sqrt(np.mean(e ** 2)) / mt, 'truth_noise': sig / mt,
                        'rms_over_noise': np.sqrt(np.mean(e ** 2)) / sig}
        rows.append(row)
        print('frame %d' % f)
        for key, v in row.items():
            if isinstance(v, dict):
                print('  %-20s blocks=%5d bias %+6.1f%%  rms %5.1f%%  truth σ %5.1f%%  rms/σ %.2f' % (
                    key, v['pixels'], 100 * v['bias'], 100 * v['rms'], 100 * v['truth_noise'],
                    v['rms_over_noise']))
    if jpath:
        json.dump(rows, open(jpath, 'w'), indent=1)


main()
