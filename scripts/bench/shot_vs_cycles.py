#!/usr/bin/env python3
"""Our differential render of the dev plate's insert against Blender Cycles' shadow catcher.

    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/shot_vs_cycles.py \
        --frames 24 [--samples 16,64,256] [--default] [--camera true|solved] [--ours-spp 256] \
        [--out DIR] [--json out.json] [--cycles-only] [--reuse [--rescore]]

(VFXGRAPH=path/to/vfxgraph, default target/release/vfxgraph; the once-nodes of
graphs/dev_plate_shot.yaml must be in its cache.)

The same insert (scene.json's two CG spheres, their materials as Cycles' truth frames had them) on
the same plate (the JPEG plate frame decoded with the sRGB curve, as `read_image_sequence` does)
rendered by Cycles (Blender 5.0.1, CPU, 2 threads) the usual way: film transparent, the two
spheres, a 10 m ground plane flagged as shadow catcher with a uniform diffuse colour (our
`fit_catcher` colour, graphs/out/dev_plate_shot/fit.json, mapped back from the solve's frame:
the colour is frame-free), the set's dome (`empty_warehouse_01`, Blender Z rotation 40°, strength
1), the truth's pixel filter and bounce limits, no denoising; the camera is the **true** one
(cameras_gt.json) and the spheres sit at their true positions — Cycles is given the exact camera
and placement that our composite has to solve and measure. With `--camera solved` it gets ours
instead (the solved camera mapped to the set's world by the placement's similarity: the
registration our composite uses; `solved_camera`), so the comparison is of the renderers alone. Composited over the plate as Blender's
manual says: `combined.rgb + (1 − combined.a) · plate · shadow_catcher`. No proxies and no
textured catcher: Cycles' catcher is one plane of one colour, so its mirror sees a flat floor.

Ours: `vfxgraph exec graphs/dev_plate_shot.yaml --node shot --node composite_exr --frames F`
at the graph's settings (adaptive, at most `--ours-spp` samples a pixel, the ratio matte) with a fresh seed (so it computes), the once-nodes already cached (run the README's `exec` of
them first); its composite is read from graphs/out/dev_plate_shot/composite.%04d.exr.

Both are timed as the CPU seconds of the child process that renders (resource.getrusage of
children: the machine is shared, so wall time alone would count other engineers' work) and as
wall seconds; the Cycles child also reports the CPU seconds of `bpy.ops.render.render()` alone.
Errors per region from scripts/bench/dev_plate_regions.py (rms/σ and bias against the truth
frames). (a) Equal time: Cycles at the sample count whose CPU time equals ours, interpolated
log-linearly between the ladder's runs (error ∝ time^−½ between them); (b) Cycles' default:
4096 samples with adaptive sampling (threshold 0.01), rendered only inside a border around the
spheres and their shadow regions (`pixel_fraction` of the frame; its time is for that border
only). The "own error" of a composite in a region is
√(rms² − σ_truth²): its error with the truth's own 32-spp noise taken out. The equal-error time
ratio per region: the CPU time Cycles needs (same interpolation, extrapolated as time^−½ beyond the ladder when its
error is still falling as noise) to reach our own error there, over ours; `never` when Cycles' error
at its most samples is still above ours and dominated by its bias.
"""
import json, os, resource, subprocess, sys, time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.abspath(os.path.join(HERE, '..', '..'))
DATA = os.path.abspath(os.path.join(REPO, '..', 'shared', 'data', 'blender_plate_dev'))
HDRI = os.path.abspath(os.path.join(REPO, '..', 'shared', 'data', 'polyhaven_hdri_1k',
                                    'empty_warehouse_01_1k.hdr'))
REGIONS = ('diffuse', 'mirror_floor', 'mirror_ground', 'mirror_box', 'diffuse_shadow', 'mirror_shadow')


def child_rusage():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd, **kw):
    """Runs cmd; (CPU seconds of the child, wall seconds, completed process)."""
    c0, w0 = child_rusage(), time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True, **kw)
    cpu, wall = child_rusage() - c0, time.monotonic() - w0
    if p.returncode != 0:
        sys.exit('failed: %s\n%s\n%s' % (' '.join(cmd), p.stdout[-3000:], p.stderr[-3000:]))
    return cpu, wall, p


# ---------------------------------------------------------------------------------------------
# The Cycles child: builds the scene, renders one frame, writes the composite.

def read_exr_uncompressed(path):
    """The channels of an uncompressed scanline float EXR, single- or multi-part (Blender 5 writes
    multilayer EXRs as multi-part files): {part.channel name: h×w array}, row 0 = top."""
    import numpy as np
    b = open(path, 'rb').read()
    assert b[:4] == b'\x76\x2f\x31\x01', 'not an EXR'
    multipart = bool(b[5] & 0x10)
    pos = 8
    parts = []
    while True:
        chans, dw, comp, pname = [], None, None, ''
        while b[pos] != 0:
            e = b.index(b'\0', pos); name = b[pos:e].decode(); pos = e + 1
            e = b.index(b'\0', pos); pos = e + 1
            size = int.from_bytes(b[pos:pos + 4], 'little'); pos += 4
            val = b[pos:pos + size]; pos += size
            if name == 'channels':
                q = 0
                while val[q] != 0:
                    e = val.index(b'\0', q); cn = val[q:e].decode(); q = e + 1
                    pt = int.from_bytes(val[q:q + 4], 'little'); q += 16
                    chans.append((cn, pt))
            elif name == 'dataWindow':
                dw = np.frombuffer(val, '<i4')
            elif name == 'compression':
                comp = val[0]
            elif name == 'name':
                pname = val.decode()
        pos += 1
        assert comp == 0, 'compressed EXR (%d)' % comp
        parts.append((pname, chans, dw))
        if not multipart or b[pos] == 0:
            break
    if multipart:
        pos += 1
    out = {}
    tables = []
    for pname, chans, dw in parts:
        h = int(dw[3] - dw[1] + 1)
        tables.append(np.frombuffer(b[pos:pos + 8 * h], '<u8').astype(int)); pos += 8 * h
    size = {0: 4, 1: 2, 2: 4}
    for (pname, chans, dw), offs in zip(parts, tables):
        w, h = int(dw[2] - dw[0] + 1), int(dw[3] - dw[1] + 1)
        arrs = {n: np.empty((h, w), np.float32) for n, _ in chans}
        for off in offs:
            q = off + (4 if multipart else 0)
            y = int.from_bytes(b[q:q + 4], 'little', signed=True) - int(dw[1]); q += 8
            for n, pt in chans:
                dt = {0: '<u4', 1: '<f2', 2: '<f4'}[pt]
                arrs[n][y] = np.frombuffer(b[q:q + size[pt] * w], dt).astype(np.float32)
                q += size[pt] * w
        for n, v in arrs.items():
            out[n] = v
    return out


def regions_border(scene_j, K, R, t, w, h):
    """The render border (xmin, xmax, ymin, ymax as fractions, y up) around both spheres and their
    shadow regions (the ground within 2.5 r of each contact point, as dev_plate_regions.py)."""
    import numpy as np
    pts = []
    for s in scene_j['cg_spheres']:
        c, r = np.array(s['center']), s['radius']
        for dx in (-1, 1):
            for dy in (-1, 1):
                for dz in (-1, 1):
                    pts.append(c + r * np.array([dx, dy, dz]))
        for a in np.linspace(0, 2 * np.pi, 32, endpoint=False):
            pts.append(np.array([c[0] + 2.6 * r * np.cos(a), c[1] + 2.6 * r * np.sin(a), 0.0]))
    x = (K @ (R @ np.array(pts).T + t[:, None]))
    u, v = x[0] / x[2], x[1] / x[2]
    x0, x1 = max(0, u.min() - 8) / w, min(w, u.max() + 8) / w
    y0, y1 = max(0, v.min() - 8) / h, min(h, v.max() + 8) / h
    return x0, x1, 1 - y1, 1 - y0


def solved_camera(frame):
    """Our solved camera of `frame` in the set's world: K, R, t, C.

    graphs/out/dev_plate_shot/cameras.json holds the solve's cameras (x_cam = R x_s + t) and
    place.json the placement's similarity (x_s = s·Q·x_w + u, from the clicked marks); with both,
    x_cam = s·(R Q x_w + (R u + t)/s), the same projection as R_w = R Q, t_w = (R u + t)/s. The
    spheres and the catcher plane are placed by the same similarity, so in the world they are
    where scene.json has them, and Cycles gets exactly the registration our composite uses."""
    import numpy as np
    out = os.path.join(REPO, 'graphs', 'out', 'dev_plate_shot')
    cams = json.load(open(os.path.join(out, 'cameras.json')))
    sim = json.load(open(os.path.join(out, 'place.json')))['similarity']
    c = [c for c in cams['frames'] if c['frame'] == frame][0]
    Q, u, sc = np.array(sim['rotation']), np.array(sim['translation']), sim['scale']
    R, t = np.array(c['R']), np.array(c['t'])
    Rw, tw = R @ Q, (R @ u + t) / sc
    return np.array(c['K']), Rw, tw, -Rw.T @ tw


def render_cycles(frame, samples, adaptive, colour, out_path, border=False, solved=False):
    import bpy
    import numpy as np
    scene_j = json.load(open(os.path.join(DATA, 'scene.json')))
    cams = json.load(open(os.path.join(DATA, 'pinhole', 'cameras_gt.json')))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = 'CYCLES'
    cy = sc.cycles
    cy.device = 'CPU'
    sc.render.threads_mode = 'FIXED'
    sc.render.threads = 2
    cy.samples = samples
    cy.use_adaptive_sampling = adaptive
    cy.adaptive_threshold = 0.01
    cy.use_denoising = False
    cy.seed = 7 + frame
    r = scene_j['render']
    cy.max_bounces = r['max_bounces']
    cy.diffuse_bounces = r['diffuse_bounces']
    cy.glossy_bounces = r['glossy_bounces']
    cy.filter_width = 1.5
    sc.render.film_transparent = True
    sc.view_settings.view_transform = 'Standard'
    sc.render.resolution_x, sc.render.resolution_y = cams['width'], cams['height']
    sc.render.resolution_percentage = 100
    sc.view_layers[0].cycles.use_pass_shadow_catcher = True

    def material(name, kind, colour):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        nt = m.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        out = nt.nodes.new('ShaderNodeOutputMaterial')
        bsdf = nt.nodes.new('ShaderNodeBsdfDiffuse' if kind == 'diffuse' else 'ShaderNodeBsdfGlossy')
        bsdf.inputs['Color'].default_value = (*colour, 1.0)
        bsdf.inputs['Roughness'].default_value = 0.0
        if kind != 'diffuse':
            bsdf.distribution = 'SHARP' if 'SHARP' in [i.identifier for i in
                                                       bsdf.bl_rna.properties['distribution'].enum_items] else 'GGX'
        nt.links.new(bsdf.outputs[0], out.inputs['Surface'])
        return m

    for s in scene_j['cg_spheres']:
        bpy.ops.mesh.primitive_uv_sphere_add(segments=256, ring_count=128, radius=s['radius'],
                                             location=s['center'])
        o = bpy.context.object
        bpy.ops.object.shade_smooth()
        mt = s['material']
        if mt['type'] == 'lambert':
            o.data.materials.append(material(s['name'], 'diffuse', mt['albedo_linear_rgb']))
        else:
            o.data.materials.append(material(s['name'], 'glossy', mt['reflectance_rgb']))
    bpy.ops.mesh.primitive_plane_add(size=10.0, location=(0, 0, 0))
    ground = bpy.context.object
    ground.is_shadow_catcher = True
    ground.data.materials.append(material('catcher', 'diffuse', colour))

    world = bpy.data.worlds.new('dome')
    sc.world = world
    world.use_nodes = True
    nt = world.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    coord = nt.nodes.new('ShaderNodeTexCoord')
    mapping = nt.nodes.new('ShaderNodeMapping')
    mapping.inputs['Rotation'].default_value = (0, 0, np.radians(scene_j['dome']['blender_rotation_z_deg']))
    env = nt.nodes.new('ShaderNodeTexEnvironment')
    env.image = bpy.data.images.load(HDRI)
    bg = nt.nodes.new('ShaderNodeBackground')
    bg.inputs['Strength'].default_value = 1.0
    wo = nt.nodes.new('ShaderNodeOutputWorld')
    nt.links.new(coord.outputs['Generated'], mapping.inputs['Vector'])
    nt.links.new(mapping.outputs['Vector'], env.inputs['Vector'])
    nt.links.new(env.outputs['Color'], bg.inputs['Color'])
    nt.links.new(bg.outputs['Background'], wo.inputs['Surface'])

    # The true camera (or ours, `solved`): x ~ K(RX + t), looking down +z with y down;
    # Blender's looks down −z, y up.
    cam_j = [c for c in cams['frames'] if c['frame'] == frame][0]
    K = np.array(cams['K']); R = np.array(cam_j['R']); C = np.array(cam_j['C'])
    t_cam = np.array(cam_j['t'])
    if solved:
        K, R, t_cam, C = solved_camera(frame)
    cd = bpy.data.cameras.new('cam')
    cam = bpy.data.objects.new('cam', cd)
    sc.collection.objects.link(cam)
    sc.camera = cam
    w, h = cams['width'], cams['height']
    cd.sensor_fit = 'HORIZONTAL'
    cd.sensor_width = 36.0
    cd.lens = K[0, 0] * 36.0 / w
    cd.shift_x = (w / 2 - (K[0, 2] + 0.5)) / w
    cd.shift_y = ((K[1, 2] + 0.5) - h / 2) / w
    cd.clip_start, cd.clip_end = 0.01, 100.0
    import mathutils
    M = R.T @ np.diag([1.0, -1.0, -1.0])
    cam.matrix_world = mathutils.Matrix.Translation(C) @ mathutils.Matrix(M.tolist()).to_4x4()

    if border:
        b = regions_border(scene_j, K, R, t_cam, w, h)
        sc.render.use_border = True
        sc.render.use_crop_to_border = False
        sc.render.border_min_x, sc.render.border_max_x, sc.render.border_min_y, sc.render.border_max_y = b
    exr = out_path + '.layers.exr'
    ims = sc.render.image_settings
    if hasattr(ims, 'media_type'):  # Blender 5: multilayer is a media type
        ims.media_type = 'MULTI_LAYER_IMAGE'
        ims.file_format = 'OPEN_EXR_MULTILAYER'
    else:
        ims.file_format = 'OPEN_EXR_MULTILAYER'
    sc.render.image_settings.exr_codec = 'NONE'
    sc.render.image_settings.color_depth = '32'
    sc.render.filepath = exr
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    w0 = time.monotonic()
    bpy.ops.render.render(write_still=True)
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    render_cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
    render_wall = time.monotonic() - w0
    ch = read_exr_uncompressed(exr)
    def get(pass_name, comps):
        keys = [k for k in ch if k.rsplit('.', 1)[0].endswith(pass_name)]
        return np.stack([[ch[k] for k in keys if k.endswith('.' + c)][0] for c in comps], -1)
    rgba = get('Combined', 'RGBA')
    catch = get('Shadow Catcher', 'RGB')
    plate = load_plate(frame)
    comp = rgba[..., :3] + (1 - rgba[..., 3:4]) * plate * catch
    write_exr(out_path, comp)
    os.remove(exr)
    frac = 1.0
    if border:
        frac = (b[1] - b[0]) * (b[3] - b[2])
    print(json.dumps({'render_cpu': render_cpu, 'render_wall': render_wall,
                      'pixel_fraction': frac}))


def load_plate(frame):
    """The JPEG plate frame as linear RGB (sRGB curve), row 0 = top, as our plate reader does."""
    import bpy
    import numpy as np
    img = bpy.data.images.load(os.path.join(DATA, 'pinhole', 'plate', 'frame.%04d.jpg' % frame))
    img.colorspace_settings.name = 'Non-Color'
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    v = np.round(a.reshape(h, w, 4)[::-1, :, :3] * 255) / 255
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def write_exr(path, rgb):
    """Linear float EXR (row 0 = top) through bpy, written to a temporary then renamed."""
    import bpy
    import numpy as np
    h, w, _ = rgb.shape
    img = bpy.data.images.new('out', w, h, alpha=True, float_buffer=True)
    img.colorspace_settings.name = 'Non-Color'
    a = np.concatenate([rgb[::-1], np.ones((h, w, 1), np.float32)], -1)
    img.pixels.foreach_set(a.astype(np.float32).ravel())
    tmp = path + '.tmp.exr'
    img.filepath_raw = tmp
    img.file_format = 'OPEN_EXR'
    img.save()
    bpy.data.images.remove(img)
    os.replace(tmp, path)


# ---------------------------------------------------------------------------------------------
# The driver.

def regions(pattern, frame):
    py = sys.executable
    tmp = pattern % frame + '.regions.json'
    subprocess.run([py, os.path.join(HERE, 'dev_plate_regions.py'), pattern, str(frame),
                    '--json', tmp], check=True, capture_output=True)
    row = json.load(open(tmp))[0]
    os.remove(tmp)
    return {k: row[k] for k in REGIONS if k in row}


def excess(region):
    """A composite's own error in a region: the rms against the truth less the truth's own noise
    (rms² = own² + σ_truth² when the two are independent), in units of the truth's mean."""
    return max(region['rms'] ** 2 - region['truth_noise'] ** 2, 1e-12) ** 0.5


def interp_at_time(points, t):
    """points: [(cpu, rms)] with rms ∝ cpu^−½ between them; rms at time t (log-log interpolation,
    extrapolated with slope −½ outside)."""
    import math
    pts = sorted(points)
    if t <= pts[0][0]:
        return pts[0][1] * math.sqrt(pts[0][0] / t)
    if t >= pts[-1][0]:
        return pts[-1][1] * math.sqrt(pts[-1][0] / t)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= t <= t1:
            a = (math.log(t) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp((1 - a) * math.log(e0) + a * math.log(e1))


def time_for_error(points, e):
    """The CPU time at which the ladder's rms reaches e (log-log interpolation); beyond the last
    run, extrapolated with slope −½ only if the last step still fell at least as ~noise does
    (slope ≤ −0.3), else None (bias-limited)."""
    import math
    pts = sorted(points)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if (e0 - e) * (e1 - e) <= 0 and e0 != e1:
            a = (math.log(e) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp((1 - a) * math.log(t0) + a * math.log(t1)), 'interpolated'
    if e >= pts[0][1]:
        return pts[0][0] * (pts[0][1] / e) ** 2, 'extrapolated below the ladder'
    (t0, e0), (t1, e1) = pts[-2], pts[-1]
    slope = (math.log(e1) - math.log(e0)) / (math.log(t1) - math.log(t0))
    if slope <= -0.3:
        return t1 * (e1 / e) ** 2, 'extrapolated (slope %.2f)' % slope
    return None, 'never (last slope %.2f: bias)' % slope


def main():
    args = sys.argv[1:]
    if args and args[0] == '--render-one':
        frame, samples, adaptive, out = int(args[1]), int(args[2]), args[3] == '1', args[5]
        colour = [float(x) for x in args[4].split(',')]
        render_cycles(frame, samples, adaptive, colour, out, border='border' in args[6:],
                      solved='solved' in args[6:])
        return

    def opt(name, default):
        if name in args:
            i = args.index(name); v = args[i + 1]; del args[i:i + 2]; return v
        return default
    frames = [int(f) for f in opt('--frames', '24').split(',')]
    ladder = [int(s) for s in opt('--samples', '16,64,256').split(',')]
    out = os.path.abspath(opt('--out', os.path.join(REPO, 'graphs', 'out', 'shot_vs_cycles')))
    jpath = opt('--json', None)
    ours_spp = opt('--ours-spp', '256')
    default = '--default' in args
    # --camera solved: Cycles gets our solved camera and measured placement (solved_camera).
    solved = opt('--camera', 'true') == 'solved'
    # --reuse: Cycles runs whose composite and timing are already in --out are read, not redone;
    # --cycles-only: only the Cycles runs (ours later, with --reuse).
    reuse, cycles_only = '--reuse' in args, '--cycles-only' in args
    # --rescore (with --reuse): the stored composites' regions are measured again.
    rescore = '--rescore' in args
    os.makedirs(out, exist_ok=True)
    fit = json.load(open(os.path.join(REPO, 'graphs', 'out', 'dev_plate_shot', 'fit.json')))
    colour = fit['colour_after']
    vfx = os.environ.get('VFXGRAPH', os.path.join(REPO, 'target', 'release', 'vfxgraph'))
    results = []
    for f in frames:
        row = {'frame': f, 'catcher_colour': colour}
        runs = []
        todo = [(s, False) for s in ladder] + ([(4096, True)] if default else [])
        for s, adaptive in todo:
            name = 'cycles_%d%s%s' % (s, '_adaptive' if adaptive else '', '_solved' if solved else '')
            path = os.path.join(out, name + '.%04d.exr')
            stamp = (path % f) + '.json'
            if reuse and os.path.exists(stamp):
                r = json.load(open(stamp))
                if rescore:
                    r['regions'] = regions(path, f)
                    json.dump(r, open(stamp, 'w'), indent=1)
            else:
                cpu, wall, p = timed([sys.executable, os.path.abspath(__file__), '--render-one',
                                      str(f), str(s), '1' if adaptive else '0',
                                      ','.join(map(str, colour)), path % f]
                                     + (['border'] if adaptive else [])
                                     + (['solved'] if solved else []))
                inner = json.loads(p.stdout.strip().splitlines()[-1])
                r = {'samples': s, 'adaptive': adaptive, 'cpu': cpu, 'wall': wall,
                     'render_cpu': inner['render_cpu'], 'render_wall': inner['render_wall'],
                     'pixel_fraction': inner['pixel_fraction'], 'regions': regions(path, f)}
                json.dump(r, open(stamp, 'w'), indent=1)
            runs.append(r)
            print('frame %d cycles %s: %.1f CPU s (render %.1f), %.1f s wall' % (
                f, name, r['cpu'], r['render_cpu'], r['wall']), flush=True)
        row['cycles'] = runs
        if cycles_only:
            continue
        # Ours: the textured local scene's render of frame f with a fresh seed (so it computes).
        stamp = os.path.join(out, 'ours_%s.%04d.json' % (ours_spp, f))
        if reuse and os.path.exists(stamp):
            row['ours'] = json.load(open(stamp))
            if rescore:
                row['ours']['regions'] = regions(os.path.join(
                    REPO, 'graphs', 'out', 'dev_plate_shot', 'composite.%04d.exr'), f)
                json.dump(row['ours'], open(stamp, 'w'), indent=1)
        else:
            seed = str(int(time.time()) % 100000)
            cpu, wall, _ = timed([vfx, 'exec', '--json', 'graphs/dev_plate_shot.yaml', '--node',
                                  'shot', '--node', 'composite_exr', '--frames', str(f),
                                  '--set', 'shot.spp=%s' % ours_spp, '--set', 'shot.seed=' + seed],
                                 cwd=REPO)
            reg = regions(os.path.join(REPO, 'graphs', 'out', 'dev_plate_shot',
                                       'composite.%04d.exr'), f)
            row['ours'] = {'spp': int(ours_spp), 'cpu': cpu, 'wall': wall, 'seed': int(seed),
                           'regions': reg}
            json.dump(row['ours'], open(stamp, 'w'), indent=1)
        ours = row['ours']['regions']
        cpu, wall = row['ours']['cpu'], row['ours']['wall']
        print('frame %d ours (%s spp): %.1f CPU s, %.1f s wall' % (f, ours_spp, cpu, wall), flush=True)
        fixed = [r for r in runs if not r['adaptive']]
        row['equal_time'], row['equal_error_time_ratio'] = {}, {}
        for k in [k for k in REGIONS if k in ours]:
            pts = [(r['cpu'], excess(r['regions'][k])) for r in fixed if k in r['regions']]
            if len(pts) < 2:
                continue
            row['equal_time'][k] = interp_at_time(pts, row['ours']['cpu'])
            t, how = time_for_error(pts, excess(ours[k]))
            row['equal_error_time_ratio'][k] = {'ratio': None if t is None else t / row['ours']['cpu'],
                                                'how': how}
        results.append(row)
        print('frame %d, per region: rms/σ and bias vs the truth (rms in %% of the truth mean)' % f)
        hdr = '  %-15s %-22s' % ('region', 'ours %s spp' % ours_spp)
        for r in runs:
            hdr += ' %-22s' % ('cycles %d%s' % (r['samples'], ' adapt' if r['adaptive'] else ''))
        print(hdr + '  own error: ours, cycles@equal-time   equal-error time ratio')
        for k in [k for k in REGIONS if k in ours]:
            line = '  %-15s %4.2f (%+5.1f%%) rms %4.1f%% ' % (
                k, ours[k]['rms_over_noise'], 100 * ours[k]['bias'], 100 * ours[k]['rms'])
            for r in runs:
                v = r['regions'].get(k)
                line += ' %4.2f (%+5.1f%%) rms %4.1f%%' % (
                    v['rms_over_noise'], 100 * v['bias'], 100 * v['rms']) if v else ' ' * 23
            et = row['equal_time'].get(k)
            rt = row['equal_error_time_ratio'].get(k, {})
            line += '  %5.1f%%, %5.1f%%' % (100 * excess(ours[k]), 100 * et) if et is not None else ''
            if rt:
                line += '   %s (%s)' % ('%.2f' % rt['ratio'] if rt['ratio'] is not None else '—',
                                        rt['how'])
            print(line)
    if jpath:
        json.dump(results, open(jpath, 'w'), indent=1)


main()
