#!/usr/bin/env python3
"""The camera solve on rendered plates it was not tuned on, against COLMAP, in one run.

What it does
------------
For each plate of a seeded corpus (``--count``, ``--seed``) it writes a graph that makes and
solves the plate with vfxgraph's own nodes, and runs it (``vfxgraph run``):

1. **Make**: ``synthetic_camera_path`` (the true cameras: an orbit, a dolly in or out, a crane,
   an orbit with a crane, a slow push of 4 % of the distance, a locked-off camera, or a slow
   orbit while the lens zooms 1.5x), 8 to 120 frames, a YAML scene of one of six sets (one
   floor; one wall; a room corner; a floor with boxes; a far-field ground 40 m below; a
   cluttered table top), ``cells``-textured and lit by an overcast sky, path-traced by
   ``render`` at 480x270 or (one plate in four) 960x540, seen through a lens (``redistort``:
   pinhole at 280, 450 or 900 px for 480 wide, or a barrel or pincushion Brown-Conrady lens),
   in one of three qualities (``grain``: 16 samples a pixel, the grain of a real plate;
   ``noisy``: 4 samples; ``blur``: 16 samples, then ``blur``: a soft lens and a motion streak
   of 2-6 px), written as JPEG frames (quality 90).
2. **Solve**: ``read_image_sequence`` -> ``klt_track`` -> ``matchmove`` with the defaults, K
   given (the pinhole's, or the lens's with ``distortion`` held), or with ``--focal unknown``
   nothing but the image size; a zoom plate adds ``zoom: true`` (its K the first frame's,
   held), as a user who knows the lens zoomed and where it started would.
3. **Score** the solved cameras against the true ones with the project's metric (the
   similarity that best aligns them; relative to the first frame for a rotation-only solve).
4. **COLMAP** (pycolmap, ``--colmap``): the same JPEG frames, SIFT, sequential matching
   (overlap 10), incremental mapping with the same K fixed (PINHOLE; RADIAL with the lens's k1,
   k2 for the lens plates, held as well; a zoom plate a camera per image, its focal length
   refined from the first frame's), scored the same way; its wall time beside ours.

It prints per set, motion, lens, quality and size: plates, solved on every frame, warned, grossly wrong
(> 1 deg) without a warning, the rotation error's median, p95 and max over solved plates; the
same for COLMAP; the time of each. ``--json`` writes every plate's figures.

Run with the export clients' Python (``.ci/run`` installs pycolmap there)::

    cargo build --release
    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/rendered_corpus.py --count 100 \\
        --seed 1 [--colmap] [--focal unknown] [--json out.json]

Rendering is most of the time (about 0.3 s a frame on 2 cores); the plates are kept in
``--work`` so a second run (another ``--focal``, or ``--colmap``) renders nothing again (the
graphs share one cache).
"""

import argparse
import json
import os
import math
import random
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
import matchmove_vs_colmap as mvc  # noqa: E402  (the project's metric, the COLMAP runner)

SETS = ["floor", "wall", "corner", "boxes", "far_ground", "table"]
MOTIONS = ["orbit", "dolly_in", "dolly_out", "crane", "orbit_crane", "push", "locked", "zoom"]
LENSES = ["normal", "wide", "long", "barrel", "pincushion"]
LENGTHS = [8, 12, 24, 48, 72, 120]
QUALITIES = ["grain", "noisy", "blur"]
SIZES = [480, 480, 480, 960]  # width; height 9/16 of it


def plate_specs(count, seed):
    """Plate i: set i mod 6, motion (i mod 6 + i // 6) mod 8 (any 48 consecutive plates hold
    every pairing), lens, length, quality and size from its own seed."""
    out = []
    for i in range(count):
        rng = random.Random(seed * 100003 + i)
        out.append({
            "index": i,
            "set": SETS[i % len(SETS)],
            "motion": MOTIONS[(i % len(SETS) + i // len(SETS)) % len(MOTIONS)],
            "lens": rng.choice(LENSES),
            "frames": rng.choice(LENGTHS),
            "start": rng.uniform(-20.0, 20.0),
            "seed": rng.randrange(1 << 30),
            "quality": rng.choice(QUALITIES),
            "size": rng.choice(SIZES),
            "streak": rng.uniform(2.0, 6.0),
            "angle": rng.uniform(0.0, 180.0),
        })
    for p in out:
        if p["motion"] == "zoom" and p["lens"] in ("barrel", "pincushion"):
            p["lens"] = "normal"  # a zoom's distortion changes with its focal length: not modelled
        p["name"] = (f"{p['index']:03d}-{p['set']}-{p['motion']}-{p['lens']}-{p['frames']}f-"
                     f"{p['quality']}-{p['size']}")
    return out


def cells(size, seed, contrast=0.6, color=False):
    return {"type": "cells", "size": size, "contrast": contrast, "seed": seed,
            **({"color": True} if color else {})}


def quad(corner, e1, e2, material, texture=None):
    o = {"quad": {"corner": corner, "edge1": e1, "edge2": e2}, "material": material}
    if texture:
        o["texture"] = texture
    return o


def box(scale, rotate, translate, seed, size=0.15):
    return {"obj": str(REPO / "graphs/scenes/cube.obj"), "material": "box",
            "texture": cells(size, seed, 0.8, True),
            "transform": {"scale": scale, "rotate": [0, rotate, 0], "translate": translate}}


def scene_and_view(kind, rng):
    """The set's objects, and where the camera looks from: target, radius, height."""
    g = lambda x0, z0, sx, sz, size, seed: quad([x0, 0, z0], [sx, 0, 0], [0, 0, sz], "ground",
                                              cells(size, seed))
    if kind == "floor":
        objs = [g(-20, -20, 40, 40, 0.2, rng.randrange(1000))]
        view = ([0, 0, 0], 6.0, 2.5)
    elif kind == "wall":
        objs = [quad([-12, 0, -1], [24, 0, 0], [0, 8, 0], "ground", cells(0.2, rng.randrange(1000)))]
        view = ([0, 2, -1], 5.0, 0.4)
    elif kind == "corner":
        s = rng.randrange(1000)
        objs = [g(-3, -3, 12, 12, 0.2, s),
                quad([-3, 0, -3], [12, 0, 0], [0, 4, 0], "ground", cells(0.25, s + 1)),
                quad([-3, 0, -3], [0, 0, 12], [0, 4, 0], "ground", cells(0.25, s + 2))]
        view = ([-1.5, 1.0, -1.5], 5.0, 0.8)
    elif kind == "boxes":
        s = rng.randrange(1000)
        objs = [g(-15, -15, 30, 30, 0.25, s),
                box([0.8, 0.6, 0.8], 20, [-1.6, 0.3, -1.2], s + 1),
                box([0.6, 1.0, 0.6], 45, [1.4, 0.5, -1.5], s + 2),
                box([0.7, 0.7, 0.7], -15, [1.2, 0.35, 1.0], s + 3)]
        view = ([0, 0.3, 0], 6.0, 2.2)
    elif kind == "far_ground":
        objs = [g(-3000, -3000, 6000, 6000, 6.0, rng.randrange(1000))]
        view = ([0, 0, 0], 150.0, 40.0)
    else:  # table
        s = rng.randrange(1000)
        objs = [quad([-1.0, 0.75, -0.6], [2.0, 0, 0], [0, 0, 1.2], "ground", cells(0.05, s)),
                box([0.12, 0.2, 0.12], 10, [-0.5, 0.85, -0.2], s + 1, 0.03),
                box([0.2, 0.1, 0.15], 35, [0.3, 0.80, 0.1], s + 2, 0.03),
                box([0.1, 0.3, 0.1], -20, [0.1, 0.90, -0.35], s + 3, 0.03),
                box([0.15, 0.15, 0.15], 60, [-0.2, 0.825, 0.3], s + 4, 0.03)]
        view = ([0, 0.8, 0], 1.6, 0.6)
    scene = {"materials": {"ground": {"type": "lambert", "albedo": [0.7, 0.62, 0.52]},
                           "box": {"type": "lambert", "albedo": 0.85}},
             "objects": objs,
             # An overcast sky: every surface lit, whatever it faces (a plate exposed for it).
             "dome": {"color": [1.0, 1.0, 1.0]}}
    return scene, view


def path_params(p, view):
    target, r, h = view
    m = p["motion"]
    start = p["start"]
    if p["set"] == "corner":
        # Inside the room: from −20° the camera would start behind the wall at x = −3.
        start = 5.0 + 0.75 * (start + 20.0)
    w, h_px = dims(p)
    q = {"frames": p["frames"], "first_frame": 0, "target": target, "radius": r,
         "radius_end": r, "height": h, "crane": 0.0, "start": start, "sweep": 0.0,
         "width": w, "height_px": h_px}
    if m == "orbit":
        q["sweep"] = 35.0
    elif m == "dolly_in":
        q["radius_end"] = 0.7 * r
    elif m == "dolly_out":
        q["radius_end"] = 1.3 * r
    elif m == "crane":
        q["crane"] = 0.4 * r
    elif m == "orbit_crane":
        q["sweep"], q["crane"] = 25.0, 0.3 * r
    elif m == "push":
        q["radius_end"] = 0.96 * r
    elif m == "zoom":
        q["sweep"], q["crane"], q["zoom"] = 15.0, 0.15 * r, 1.5
    return q


def dims(p):
    return p["size"], p["size"] * 9 // 16


LENS = {  # focal (px at 480 wide), k1, k2
    "normal": (450.0, 0.0, 0.0), "wide": (280.0, 0.0, 0.0), "long": (900.0, 0.0, 0.0),
    "barrel": (420.0, -0.08, 0.01), "pincushion": (480.0, 0.06, 0.0),
}


def lens_of(p):
    """The plate's focal length (px, for its width) and k1, k2."""
    f, k1, k2 = LENS[p["lens"]]
    return f * p["size"] / 480, k1, k2


def k_json(p):
    f, k1, k2 = lens_of(p)
    W, H = dims(p)
    k = {"K": [[f, 0.0, (W - 1) / 2], [0.0, f, (H - 1) / 2], [0.0, 0.0, 1.0]],
         "width": W, "height": H}
    if k1 or k2:
        k["distortion"] = {"model": "brown_conrady", "k1": k1, "k2": k2}
    return k


def write_plate(p, work, focal_mode):
    """The plate's folder: scene, K, the make-and-solve graph. Returns the graph's path."""
    d = work / p["name"]
    d.mkdir(parents=True, exist_ok=True)
    rng = random.Random(p["seed"])
    scene, view = scene_and_view(p["set"], rng)
    (d / "scene.yaml").write_text(json.dumps(scene, indent=1))
    f, k1, k2 = lens_of(p)
    W, H = dims(p)
    (d / "lens.json").write_text(json.dumps(k_json(p), indent=1))
    q = path_params(p, view)
    q["focal"] = f
    distorted = bool(k1 or k2)
    make = {
        "path": {"type": "synthetic_camera_path", "params": q},
        "scene": {"type": "read_scene", "params": {"path": "scene.yaml"}},
        "plate": {"type": "render", "per_frame": True,
                  "inputs": {"scene": "scene.scene", "cameras": "path.cameras"},
                  "params": {"spp": 4 if p["quality"] == "noisy" else 16, "max_depth": 2}},
        "frames": {"type": "write_image_sequence",
                   "inputs": {"sequence": "soft.image" if p["quality"] == "blur"
                              else "bent.image" if distorted else "plate.image"},
                   "params": {"path": "plate/frame.####.jpg"}},
        "truth": {"type": "write_cameras", "inputs": {"cameras": "path.cameras"},
                  "params": {"path": "true_cameras.json"}},
    }
    if distorted:
        # The pinhole render covers the lens's whole footprint (K′ of `undistort`'s overscan),
        # so the lens bends a full picture: no empty border for the tracker to follow.
        make["lens"] = {"type": "read_intrinsics", "params": {"path": "lens.json"}}
        make["blank"] = {"type": "constant", "params": {"width": W, "height": H}}
        make["footprint"] = {"type": "undistort",
                             "inputs": {"image": "blank.image", "intrinsics": "lens.intrinsics"}}
        make["plate"]["inputs"]["intrinsics"] = "footprint.intrinsics"
        make["bent"] = {"type": "redistort", "per_frame": True,
                        "inputs": {"image": "plate.image", "intrinsics": "lens.intrinsics"}}
    if p["quality"] == "blur":
        make["soft"] = {"type": "blur", "per_frame": True,
                        "inputs": {"image": "bent.image" if distorted else "plate.image"},
                        "params": {"sigma": 0.7, "streak": p["streak"], "angle": p["angle"]}}
    solve = {
        "read": {"type": "read_image_sequence", "params": {"path": "plate/frame.####.jpg"}},
        "track": {"type": "klt_track", "inputs": {"frames": "read.sequence"}},
        "solve": {"type": "matchmove", "inputs": {"tracks": "track.tracks"}},
        "cameras": {"type": "write_cameras", "inputs": {"cameras": "solve.cameras"},
                    "params": {"path": f"solved_{focal_mode}.json"}},
        "report": {"type": "write_report", "inputs": {"report": "solve.report"},
                   "params": {"path": f"report_{focal_mode}.json"}},
    }
    zoom = p["motion"] == "zoom"
    if focal_mode == "known":
        solve["lens"] = {"type": "read_intrinsics", "params": {"path": "lens.json"}}
        solve["solve"]["inputs"]["intrinsics"] = "lens.intrinsics"
        if zoom:
            solve["solve"]["params"] = {"zoom": True}
    else:
        solve["solve"]["params"] = {"focal": "unknown", **({"zoom": True} if zoom else {})}
    frames = f"0..{p['frames']}"
    seed = p["seed"] % 100000
    (d / "make.yaml").write_text(json.dumps(
        {"version": 1, "seed": seed, "frames": frames, "nodes": make}, indent=1))
    g = d / f"solve_{focal_mode}.yaml"
    g.write_text(json.dumps({"version": 1, "seed": seed, "frames": frames, "nodes": solve},
                            indent=1))
    return g


def score(solved_json, truth_json, report):
    truth = mvc.load_cameras_json(truth_json)
    if not Path(solved_json).exists():
        return {"status": "failed"}
    est = mvc.load_cameras_json(solved_json)
    n = len(truth)
    rotation_only = bool(report.get("rotation_only"))
    frames = sorted(f for f in est if f in truth)
    out = {"status": "solved" if len(frames) == n else "partial", "registered": len(frames)}
    if len(frames) < 2:
        out["status"] = "failed"
        return out
    out.update(rotation_metrics(est, truth, frames, rotation_only))
    return out


def rotation_metrics(est, truth, frames, rotation_only):
    """Largest rotation error over `frames`: after the similarity (moving camera), or relative
    to the first frame (a rotation-only solve, or a camera that does not move)."""
    e = [est[f] for f in frames]
    t = [truth[f] for f in frames]
    centres = np.array([mvc.centre(*x) for x in t])
    extent = float(np.linalg.norm(centres - centres[0], axis=1).max())
    if rotation_only or extent < 1e-6:
        r0e, r0t = e[0][0], t[0][0]
        rot = [mvc.rotation_angle_deg(re_ @ r0e.T, rt @ r0t.T) for (re_, _), (rt, _) in zip(e, t)]
    else:
        rot, _ = mvc.aligned_errors(e, t)
    return {"rot_max_deg": float(max(rot)), "rot_median_deg": float(np.median(rot))}


def run_colmap(p, work, threads):
    d = work / p["name"]
    f, k1, k2 = lens_of(p)
    W, H = dims(p)
    mvc.FX = mvc.FY = f
    mvc.CX, mvc.CY = (W - 1) / 2, (H - 1) / 2
    log = []
    cx, cy = (W - 1) / 2 + mvc.COLMAP_PIXEL_SHIFT, (H - 1) / 2 + mvc.COLMAP_PIXEL_SHIFT
    # The same K and lens as ours, held: RADIAL's k1, k2 act on normalized coordinates, as ours.
    known = ("RADIAL", [f, cx, cy, k1, k2]) if (k1 or k2) else ("PINHOLE", [f, f, cx, cy])
    t0 = time.perf_counter()
    try:
        r = mvc.run_colmap(str(d / "plate"), d, threads, log, known_camera=known,
                           zoom=p["motion"] == "zoom")
    except Exception as e:  # a COLMAP failure is a result, not a crash of the benchmark
        return {"status": "failed", "error": str(e)[:200], "seconds": time.perf_counter() - t0}
    seconds = time.perf_counter() - t0
    truth = mvc.load_cameras_json(d / "true_cameras.json")
    est = r.get("cameras", {})
    frames = sorted(fr for fr in est if fr in truth)
    out = {"seconds": seconds, "registered": len(frames)}
    if len(frames) < 3:
        out["status"] = "failed"
        return out
    out["status"] = "solved" if len(frames) == len(truth) else "partial"
    out.update(rotation_metrics(est, truth, frames, False))
    return out


def quantile(v, q):
    v = sorted(v)
    return v[round((len(v) - 1) * q)] if v else float("nan")


def table(title, rows, key, who):
    groups = {}
    for r in rows:
        groups.setdefault(r["spec"][key] if key else "all", []).append(r)
    print(f"\n{title:<12} plates solved warned silent>1°  rot p50°  rot p95°  rot max°")
    for k in sorted(groups):
        v = [r[who] for r in groups[k]]
        solved = [x for x in v if x.get("status") == "solved"]
        warned = [x for x in solved if x.get("warnings")]
        wrong = [x for x in solved if x["rot_max_deg"] > 1.0 and not x.get("warnings")]
        rot = [x["rot_max_deg"] for x in solved]
        print(f"{k:<12} {len(v):>6} {len(solved):>6} {len(warned):>6} {len(wrong):>10} "
              f"{quantile(rot, .5):>9.3f} {quantile(rot, .95):>9.3f} {quantile(rot, 1):>9.3f}")


def summarize(rows, focal, colmap):
    for who in ["ours"] + (["colmap"] if colmap else []):
        mine = [r for r in rows if who in r]
        print(f"\n=== {who} (focal {focal if who == 'ours' else 'known'}), {len(mine)} plates")
        for key in ["set", "motion", "lens", "quality", "size", None]:
            table(key or "corpus", mine, key, who)
    bad = [r for r in rows if r["ours"]["status"] != "solved" or r["ours"]["rot_max_deg"] > 1.0]
    if bad:
        print("\nours not solved on every frame, or over 1°:")
        for r in bad:
            o = r["ours"]
            print(f"  {r['spec']['name']:<48} {o['status']:>7} "
                  f"{o.get('rot_max_deg', float('nan')):7.3f}° "
                  f"{'warned' if o.get('warnings') else 'SILENT' if o['status'] == 'solved' else ''}")
    if colmap:
        paired = [r for r in rows if "colmap" in r]
        both = [r for r in paired if r["colmap"]["status"] == "solved"]
        good = [r for r in both if r["ours"]["status"] == "solved"
                and r["ours"]["rot_max_deg"] <= r["colmap"]["rot_max_deg"] + 1e-9]
        t_ours = sum(r["ours"]["solve_seconds"] for r in paired)
        t_colmap = sum(r["colmap"]["seconds"] for r in paired)
        print(f"\nCOLMAP solved {len(both)} of {len(rows)}; ours at least as accurate on "
              f"{len(good)} of those; time: COLMAP {t_colmap:.1f} s, our read + track + solve "
              f"{t_ours:.1f} s ({t_colmap / max(t_ours, 1e-9):.1f}x)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--first", type=int, default=0, help="skip the plates before this one")
    ap.add_argument("--focal", choices=["known", "unknown"], default="known")
    ap.add_argument("--colmap", action="store_true", help="COLMAP on the same frames too")
    ap.add_argument("--colmap-from", metavar="JSON",
                    help="COLMAP's figures from an earlier run's --json of the same plates "
                         "(COLMAP's result does not depend on ours: re-solve without re-running it)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default=str(Path.home() / ".cache/vfxgraph/rendered-corpus"))
    ap.add_argument("--vfxgraph", default=str(REPO / "target/release/vfxgraph"))
    ap.add_argument("--json", help="every plate's figures (written after each plate)")
    ap.add_argument("--summarize", nargs="+", metavar="JSON",
                    help="print the tables of earlier runs' --json files (joined) and stop")
    a = ap.parse_args()
    os.environ.setdefault("GLOG_minloglevel", "2")  # COLMAP's own log: errors only
    if a.summarize:
        rows = [r for f in a.summarize for r in json.loads(Path(f).read_text())]
        summarize(rows, a.focal, all("colmap" in r for r in rows))
        return
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    cache = work / "cache"
    earlier = {}
    if a.colmap_from:
        earlier = {r["spec"]["name"]: r["colmap"] for r in json.loads(Path(a.colmap_from).read_text())
                   if "colmap" in r}
    rows = []
    for p in plate_specs(a.count, a.seed)[a.first:]:
        g = write_plate(p, work, a.focal)
        d = g.parent
        make = subprocess.run([a.vfxgraph, "run", "-q", "--cache", str(cache),
                               str(d / "make.yaml")], capture_output=True, text=True)
        if make.returncode != 0:
            sys.exit(f"{p['name']}: making the plate failed: {make.stderr[-2000:]}")
        # The solve from the frames on disk, nothing cached: read, track, solve, timed.
        for old in (d / f"solved_{a.focal}.json", d / f"report_{a.focal}.json"):
            old.unlink(missing_ok=True)
        t0 = time.perf_counter()
        run = subprocess.run([a.vfxgraph, "run", "-q", "--no-cache", "-j", str(a.threads),
                              str(g)], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        report_file = d / f"report_{a.focal}.json"
        report = json.loads(report_file.read_text()) if run.returncode == 0 else {}
        ours = score(d / f"solved_{a.focal}.json", d / "true_cameras.json", report)
        ours["warnings"] = report.get("warnings", [])
        ours["run_seconds"] = wall
        ours["solve_seconds"] = wall
        if run.returncode != 0:
            ours["error"] = run.stderr.strip().splitlines()[-1:] if run.stderr else []
        row = {"spec": p, "ours": ours}
        if a.colmap:
            row["colmap"] = run_colmap(p, work, a.threads)
        elif p["name"] in earlier:
            row["colmap"] = earlier[p["name"]]
        rows.append(row)
        if a.json:
            Path(a.json).write_text(json.dumps(rows, indent=1, default=float))
        c = row.get("colmap", {})
        print(f"{p['name']:<38} ours {ours['status']:>7} {ours.get('rot_max_deg', float('nan')):7.3f}° "
              f"w{len(ours['warnings'])}"
              + (f"  colmap {c['status']:>7} {c.get('rot_max_deg', float('nan')):7.3f}° "
                 f"{c['seconds']:6.1f} s" if c else ""), flush=True)
    summarize(rows, a.focal, a.colmap or bool(earlier))


if __name__ == "__main__":
    main()
