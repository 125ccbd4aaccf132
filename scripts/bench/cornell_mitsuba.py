#!/usr/bin/env python3
"""Reference and equal-time comparison of our path tracer against Mitsuba 3 on the book's Cornell box.

    pip install mitsuba numpy
    python3 scripts/bench/cornell_mitsuba.py [--width 320 --height 240] [--ref-spp 1024]
        [--budget 10] [--variant scalar_rgb] [--threads 2]

Builds the SAME scene in Mitsuba from the JSON our renderer dumps (the `render_scn` example with
`--dump-scene`), so both read one description:
  * Lambert -> twosided diffuse; mirror -> twosided conductor (material none) scaled by its
    reflectance; the Blinn-Phong lobes are dropped in BOTH renderers (`--diffuse-only`: Mitsuba
    has no Blinn-Phong BSDF) so the spheres are diffuse with the .scn's kd*d_col.
  * Area lights: Mitsuba's are one-sided; each light triangle is wound to face the scene's
    centre (ours emit on both faces; the back faces of the book's light face the ceiling 1e-4
    away, a negligible difference).
  * Camera: perspective, fov across x, box reconstruction filter, independent sampler (ours:
    box-filtered jittered samples). Max depth: Mitsuba counts the emitter segment, so
    max_depth = ours + 1 (= 4 for the book's 3 bounces); RR off in Mitsuba (rr_depth > max_depth).

Figures printed: relative RMSE = RMSE / mean(reference) over all pixels and channels.
  1. Mitsuba reference at --ref-spp (seed 1).
  2. Ours at --ref-spp (seed 2) vs the reference, next to the noise floor expected from the two
     renders' variances (ours from our variance image, Mitsuba's from two half-spp renders).
  3. Equal time: ours with --budget seconds of wall time vs Mitsuba with the spp that fits the
     same wall time; the RMSE of each to the reference and their ratio (goal <= 1).
Timings are wall clock on a shared machine: noisy; each timed render is best of --repeat runs.
"""
import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCN = os.path.join(ROOT, "..", "shared", "data", "book-demo", "cornell.scn")
EXE = os.path.join(ROOT, "target", "release", "examples", "render_scn")


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    c = 3 if kind == b"PF" else 1
    return data.reshape(h, w, c)[::-1].astype(np.float64)


def ours(args, spp=None, budget=None, seed=0, out="/tmp/vfx_bench/ours"):
    cmd = [EXE, SCN, "--width", str(args.width), "--height", str(args.height), "--diffuse-only",
           "--max-depth", str(args.max_depth), "--threads", str(args.threads), "--seed", str(seed),
           "--out", out]
    cmd += ["--spp", str(spp)] if budget is None else ["--time-budget", str(budget)]
    res = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    return read_pfm(out + ".pfm"), res


def build_mitsuba_scene(mi, scene):
    cam = scene["camera"]
    k, r, t = np.array(cam["k"]), np.array(cam["r"]), np.array(cam["t"])
    w, h = cam["width"], cam["height"]
    assert abs(k[0, 0] - k[1, 1]) < 1e-9 * k[0, 0] and k[0, 1] == 0, "square pixels, no skew"
    assert abs(k[0, 2] - (w - 1) / 2) < 1e-9 and abs(k[1, 2] - (h - 1) / 2) < 1e-9, "centred"
    c = -r.T @ t
    fov = np.degrees(2 * np.arctan((w / 2) / k[0, 0]))
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": scene["_max_depth"] + 1, "rr_depth": 1000},
        "sensor": {
            "type": "perspective", "fov": float(fov), "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=c.tolist(), target=(c + r[2]).tolist(),
                                                       up=(-r[1]).tolist()),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": 1},
        },
    }
    allv = []

    def bsdf_of(mat):
        if mat["type"] == "lambert":
            a = mat["albedo"]
            inner = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [a["r"], a["g"], a["b"]]}}
        elif mat["type"] == "mirror":
            rr = mat["reflectance"]
            inner = {"type": "conductor", "material": "none",
                     "specular_reflectance": {"type": "rgb", "value": [rr["r"], rr["g"], rr["b"]]}}
        else:
            raise SystemExit(f"material {mat['type']} has no Mitsuba equivalent; use --diffuse-only")
        return {"type": "twosided", "bsdf": inner}

    def v3(p):
        return [p["x"], p["y"], p["z"]]

    for o in scene["objects"] + scene["shadow_catchers"]:
        for s in [o["shape"]]:
            if s["type"] == "triangles":
                for tri in s["triangles"]:
                    allv += [v3(p) for p in tri]
    centre = np.mean(np.array(allv), axis=0) if allv else np.zeros(3)
    n = 0
    shapes = {}
    for o in scene["objects"] + scene["shadow_catchers"]:
        s = o["shape"]
        if s["type"] == "sphere":
            shapes[f"s{n}"] = {"type": "sphere", "center": v3(s["center"]), "radius": s["radius"],
                               "bsdf": bsdf_of(o["material"])}
        else:
            tris = [[v3(p) for p in tri] for tri in s["triangles"]]
            shapes[f"s{n}"] = ("mesh", tris, bsdf_of(o["material"]), None)
        n += 1
    for light in scene["lights"]:
        L = light["radiance"]
        tris = []
        for tri in light["triangles"]:
            a, b, cc = (np.array(v3(p)) for p in tri)
            nrm = np.cross(b - a, cc - a)
            if np.dot(nrm, centre - (a + b + cc) / 3) < 0:
                b, cc = cc, b
            tris.append([a.tolist(), b.tolist(), cc.tolist()])
        shapes[f"s{n}"] = ("mesh", tris, {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
                           {"type": "area", "radiance": {"type": "rgb", "value": [L["r"], L["g"], L["b"]]}})
        n += 1
    for name, s in shapes.items():
        if isinstance(s, tuple):
            _, tris, bsdf, emitter = s
            path = f"/tmp/vfx_bench/{name}.obj"
            with open(path, "w") as f:
                for tri in tris:
                    for p in tri:
                        f.write("v %.17g %.17g %.17g\n" % tuple(p))
                for i in range(len(tris)):
                    f.write(f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}\n")
            d[name] = {"type": "obj", "filename": path, "face_normals": True, "bsdf": bsdf}
            if emitter is not None:
                d[name]["emitter"] = emitter
        else:
            d[name] = s
    return mi.load_dict(d)


def mitsuba_render(mi, scene_obj, spp, seed):
    t0 = time.perf_counter()
    img = mi.render(scene_obj, spp=spp, seed=seed)
    arr = np.array(img, dtype=np.float64)
    return arr[..., :3], time.perf_counter() - t0


def rel_rmse(a, ref):
    return float(np.sqrt(np.mean((a - ref) ** 2)) / np.mean(ref))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--max-depth", type=int, default=3)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--budget", type=float, default=10.0, help="equal-time wall seconds")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--variant", default="scalar_rgb")
    args = ap.parse_args()
    if not os.path.exists(SCN):
        sys.exit(f"{SCN} is missing")
    if not os.path.exists(EXE):
        subprocess.run(["cargo", "build", "--release", "-p", "vfxgraph-render", "--example", "render_scn"],
                       cwd=ROOT, check=True)
    os.makedirs("/tmp/vfx_bench", exist_ok=True)
    import mitsuba as mi
    mi.set_variant(args.variant)
    mi.set_log_level(mi.LogLevel.Warn)
    try:
        mi.set_thread_count(args.threads)
    except AttributeError:
        pass
    dump = "/tmp/vfx_bench/scene.json"
    subprocess.run([EXE, SCN, "--width", str(args.width), "--height", str(args.height), "--diffuse-only",
                    "--spp", "1", "--dump-scene", dump, "--out", "/tmp/vfx_bench/dump"], check=True,
                   capture_output=True)
    scene = json.load(open(dump))
    scene["_max_depth"] = args.max_depth
    ms = build_mitsuba_scene(mi, scene)

    print(f"# Cornell box {args.width}x{args.height}, max_depth {args.max_depth} (Mitsuba {args.max_depth + 1}), "
          f"{args.threads} threads, Mitsuba {mi.__version__} {args.variant}")
    half = args.ref_spp // 2
    ref_a, ta = mitsuba_render(mi, ms, half, 1)
    ref_b, tb = mitsuba_render(mi, ms, half, 1001)
    ref = 0.5 * (ref_a + ref_b)
    # Variance of the reference's pixel means from its two halves.
    var_ref = ((ref_a - ref_b) ** 2) / 4.0
    print(f"reference: Mitsuba {args.ref_spp} spp in {ta + tb:.1f} s")
    np.save("/tmp/vfx_bench/ref.npy", ref)

    ours_hi, res = ours(args, spp=args.ref_spp, seed=2, out="/tmp/vfx_bench/ours_hi")
    # Our variance of the mean: re-estimate from two half renders as for Mitsuba.
    o1, _ = ours(args, spp=half, seed=3, out="/tmp/vfx_bench/o1")
    o2, _ = ours(args, spp=half, seed=4, out="/tmp/vfx_bench/o2")
    var_ours = ((o1 - o2) ** 2) / 4.0
    noise = float(np.sqrt(np.mean(var_ref + var_ours)) / np.mean(ref))
    print(f"ours {args.ref_spp} spp ({res['render_seconds']:.1f} s) vs reference: relative RMSE "
          f"{rel_rmse(ours_hi, ref):.4f}; expected from noise alone {noise:.4f}; "
          f"mean ratio ours/ref {np.mean(ours_hi) / np.mean(ref):.4f}")

    # Equal time.
    best = None
    for _ in range(args.repeat):
        img, r = ours(args, budget=args.budget, seed=5, out="/tmp/vfx_bench/ours_eq")
        if best is None or r["render_seconds"] < best[1]["render_seconds"]:
            best = (img, r)
    ours_eq, r = best
    t_ours = r["render_seconds"] + 0.0
    # Mitsuba spp fitting the same wall time, from a probe.
    _, tp = mitsuba_render(mi, ms, 4, 7)
    _, tp = mitsuba_render(mi, ms, 4, 7)
    m_spp = max(1, int(4 * t_ours / tp))
    best_m = None
    for _ in range(args.repeat):
        img, tm = mitsuba_render(mi, ms, m_spp, 9)
        if best_m is None or tm < best_m[1]:
            best_m = (img, tm)
    mit_eq, tm = best_m
    e_ours, e_mit = rel_rmse(ours_eq, ref), rel_rmse(mit_eq, ref)
    print(f"equal time: ours {r['spp']} spp in {t_ours:.2f} s -> relative RMSE {e_ours:.4f}; "
          f"Mitsuba {m_spp} spp in {tm:.2f} s -> {e_mit:.4f}; "
          f"ratio ours/Mitsuba {e_ours / e_mit:.3f} (goal <= 1); "
          f"samples per second ours/Mitsuba {r['spp'] / t_ours / (m_spp / tm):.2f}")


if __name__ == "__main__":
    main()
