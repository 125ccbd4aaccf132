#!/usr/bin/env python3
"""The camera solve on the robustness corpus against COLMAP, in one run.

What it does
------------
1. Runs ``cargo run --release -p vfxgraph-matchmove --example solve_corpus -- COUNT SEED`` with
   ``VFXGRAPH_CORPUS_EXPORT`` set: every plate of the corpus (``matchmove::corpus``: seven sets x
   nine motions, 8-200 frames, 960x540) is solved by our matchmove with its defaults (K given),
   scored against its true cameras, and written out (tracks, K, truth).
2. Gives COLMAP (pycolmap 4.2.1) the *same tracks* as matches: one PINHOLE camera with the same K
   (held fixed in the mapper's bundle adjustment and absolute-pose registration), every track
   observation a keypoint, sequential pairs (each frame with the next ``--overlap`` frames) matched
   by track identity, COLMAP's own geometric verification, then incremental mapping.
   Nothing else differs: no images, no SIFT, so both solvers see exactly the same correspondences
   and the comparison is of the solvers alone.
3. Scores COLMAP's largest reconstruction like ours: rotation error after the similarity that best
   aligns the registered frames to the truth (relative to the first frame for a camera that does
   not move, whose centres admit no similarity). A plate counts as solved when every frame is
   registered. COLMAP's mapper keeps its defaults, among them an initial pair whose median
   triangulation angle is at least 16 degrees (``--init-tri-angle`` lowers it).

It prints, per set and per motion: plates, solved (all frames), grossly wrong (> 1 deg), the
rotation error's median and p95 over solved plates, for both, and the wall time of each, with
their ratio.

Run with the export clients' Python (``.ci/run`` installs pycolmap there)::

    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/corpus_vs_colmap.py [--count 63] [--seed 1]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    import pycolmap
except ImportError:
    sys.exit("pycolmap is needed: pip install pycolmap==4.2.1")

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
# The project's metric, shared with the plate benchmark.
from matchmove_vs_colmap import centre, nearest_rotation, rotation_angle_deg, set_if  # noqa: E402

# Mapper options this pycolmap lacks (reported once at the end).
MISSING_OPTIONS = []


def rotation_errors(est, truth):
    """est, truth: lists of (R, t) for the same frames: per-frame rotation errors (degrees)."""
    cs = np.array([centre(r, t) for r, t in truth])
    extent = float(np.max(np.linalg.norm(cs - cs[0], axis=1))) if len(cs) else 0.0
    if extent > 1e-9 and len(est) >= 3:
        m = sum(rg.T @ re_ for (re_, _), (rg, _) in zip(est, truth))
        ra = nearest_rotation(m)
        return [rotation_angle_deg(re_ @ ra.T, rg) for (re_, _), (rg, _) in zip(est, truth)]
    r0e, r0t = est[0][0], truth[0][0]
    return [rotation_angle_deg(re_ @ r0e.T, rg @ r0t.T) for (re_, _), (rg, _) in zip(est, truth)]


def colmap_solve(plate, work, overlap, threads, init_tri_angle=None):
    """COLMAP's incremental mapping on the plate's tracks; {frame: (R, t)} and the time."""
    work.mkdir(parents=True, exist_ok=True)
    db_path = work / "database.db"
    if db_path.exists():
        db_path.unlink()
    f, cx, cy = plate["k"]
    w, h = plate["size"]
    n = plate["frames"]
    # Keypoints per frame, and each track's keypoint index in each frame it is seen in.
    kps = [[] for _ in range(n)]
    index = {}
    for t in plate["tracks"]:
        for j, p in enumerate(t["points"]):
            fr = t["first"] + j
            index[(t["id"], fr)] = len(kps[fr])
            # COLMAP's pixel (0, 0) is the top-left pixel's corner, ours its centre.
            kps[fr].append((p[0] + 0.5, p[1] + 0.5))
    t0 = time.perf_counter()
    db = pycolmap.Database.open(str(db_path))
    cam = pycolmap.Camera(model="PINHOLE", width=w, height=h,
                          params=[f, f, cx + 0.5, cy + 0.5])
    cam.has_prior_focal_length = True
    cam_id = db.write_camera(cam)
    rig = pycolmap.Rig()
    rig.add_ref_sensor(pycolmap.sensor_t(pycolmap.SensorType.CAMERA, cam_id))
    rig_id = db.write_rig(rig)
    image_ids = []
    for fr in range(n):
        frame = pycolmap.Frame()
        frame.rig_id = rig_id
        image = pycolmap.Image(name=f"{fr:05d}.png", camera_id=cam_id)
        image_id = db.write_image(image)
        frame.add_data_id(pycolmap.data_t(pycolmap.sensor_t(pycolmap.SensorType.CAMERA, cam_id),
                                          image_id))
        db.write_frame(frame)
        image_ids.append(image_id)
        pts = np.array(kps[fr], np.float32).reshape(-1, 2)
        db.write_keypoints(image_id, pts)
    pairs = []
    by_frame = [dict() for _ in range(n)]
    for (tid, fr), k in index.items():
        by_frame[fr][tid] = k
    for a in range(n):
        for b in range(a + 1, min(n, a + 1 + overlap)):
            common = [(by_frame[a][t], by_frame[b][t]) for t in by_frame[a] if t in by_frame[b]]
            if len(common) < 8:
                continue
            db.write_matches(image_ids[a], image_ids[b], np.array(common, np.uint32))
            pairs.append((a, b))
    db.close()
    pairs_path = work / "pairs.txt"
    pairs_path.write_text("".join(f"{a:05d}.png {b:05d}.png\n" for a, b in pairs))
    pycolmap.verify_matches(str(db_path), str(pairs_path))
    opts = pycolmap.IncrementalPipelineOptions()
    opts.num_threads = threads
    opts.ba_refine_focal_length = False
    opts.ba_refine_principal_point = False
    opts.ba_refine_extra_params = False
    opts.random_seed = 1
    mapper = opts.mapper
    for name, value in [("abs_pose_refine_focal_length", False),
                        ("abs_pose_refine_extra_params", False), ("num_threads", threads),
                        ("random_seed", 1)]:
        set_if(mapper, name, value, MISSING_OPTIONS)
    if init_tri_angle is not None:
        mapper.init_min_tri_angle = init_tri_angle
    opts.mapper = mapper
    (work / "sparse").mkdir(exist_ok=True)
    recs = pycolmap.incremental_mapping(str(db_path), str(work), str(work / "sparse"),
                                        options=opts)
    seconds = time.perf_counter() - t0
    if not recs:
        return {}, seconds
    rec = recs[max(recs, key=lambda k: recs[k].num_reg_images())]
    cams = {}
    for img in rec.images.values():
        if hasattr(img, "has_pose") and not img.has_pose:
            continue
        p = img.cam_from_world
        p = p() if callable(p) else p
        cams[int(img.name.split(".")[0])] = (np.array(p.rotation.matrix(), float),
                                              np.array(p.translation, float).reshape(3))
    return cams, seconds


def table(title, groups, key):
    print(f"\n{title:<12} plates | ours: solved >1deg  p50 deg  p95 deg | "
          "COLMAP: solved >1deg  p50 deg  p95 deg | COLMAP solved, ours at least as accurate")
    for name in sorted(groups):
        rows = groups[name]

        def stats(side):
            solved = [r[side] for r in rows if r[side] is not None]
            rot = sorted(s for s in solved)
            wrong = sum(1 for s in rot if s > 1.0)
            p = (lambda q: rot[min(len(rot) - 1, int(round(q * (len(rot) - 1))))] if rot
                 else float("nan"))
            return len(solved), wrong, p(0.5), p(0.95)

        o, c = stats("ours"), stats("colmap")
        both = [r for r in rows if r["colmap"] is not None]
        better = sum(1 for r in both if r["ours"] is not None and r["ours"] <= r["colmap"] * 1.0001)
        print(f"{name:<12} {len(rows):>6} | {o[0]:>12} {o[1]:>5} {o[2]:>8.3f} {o[3]:>8.3f} | "
              f"{c[0]:>14} {c[1]:>5} {c[2]:>8.3f} {c[3]:>8.3f} | {better}/{len(both)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--count", type=int, default=63)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--overlap", type=int, default=10, help="sequential pairs per frame")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--init-tri-angle", type=float, default=None,
                    help="COLMAP's init_min_tri_angle (its default: 16 degrees)")
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="corpus_vs_colmap-"))
    export = work / "plates"
    ours_json = work / "ours.json"
    env = dict(os.environ, VFXGRAPH_CORPUS_EXPORT=str(export))
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "vfxgraph-matchmove", "--example",
                    "solve_corpus"], cwd=REPO, check=True)
    t0 = time.perf_counter()
    subprocess.run(["cargo", "run", "--release", "-q", "-p", "vfxgraph-matchmove", "--example",
                    "solve_corpus", "--", str(args.count), str(args.seed), "calibrated",
                    str(ours_json)], cwd=REPO, env=env, check=True, stdout=subprocess.DEVNULL)
    ours_wall = time.perf_counter() - t0
    ours = {o["name"]: o for o in json.loads(ours_json.read_text())}
    rows = []
    colmap_wall = 0.0
    for i, path in enumerate(sorted(export.glob("*.json"))):
        plate = json.loads(path.read_text())
        truth = [(np.array(c["r"]), np.array(c["t"])) for c in plate["truth"]]
        cams, seconds = colmap_solve(plate, work / "colmap" / plate["name"], args.overlap,
                                     args.threads, args.init_tri_angle)
        colmap_wall += seconds
        colmap_rot = None
        if len(cams) == plate["frames"]:
            frames = sorted(cams)
            colmap_rot = max(rotation_errors([cams[f] for f in frames],
                                             [truth[f] for f in frames]))
        o = ours[plate["name"]]
        ours_rot = o["rotation_max_deg"] if o["status"] == "solved" else None
        rows.append({"name": plate["name"], "set": plate["spec"]["set"],
                     "motion": plate["spec"]["motion"], "ours": ours_rot, "colmap": colmap_rot,
                     "colmap_registered": len(cams), "frames": plate["frames"],
                     "colmap_seconds": seconds, "ours_seconds": o["seconds"],
                     "ours_warned": bool(o["warnings"])})
        print(f"{i + 1:>4} {plate['name']:<48} ours {ours_rot if ours_rot is None else round(ours_rot, 3)}"
              f"  COLMAP {len(cams)}/{plate['frames']} frames "
              f"{colmap_rot if colmap_rot is None else round(colmap_rot, 3)} in {seconds:.1f} s",
              flush=True)
    by_set, by_motion = {}, {}
    for r in rows:
        by_set.setdefault(r["set"], []).append(r)
        by_motion.setdefault(r["motion"], []).append(r)
    table("set", by_set, "set")
    table("motion", by_motion, "motion")
    table("corpus", {"all": rows}, "all")
    ours_cpu = sum(r["ours_seconds"] for r in rows)
    colmap_cpu = sum(r["colmap_seconds"] for r in rows)
    print(f"\nwall: ours {ours_wall:.1f} s for {len(rows)} plates (solves in parallel, "
          f"{ours_cpu:.1f} s summed), COLMAP {colmap_wall:.1f} s (plates one after another, "
          f"{args.threads} threads each): COLMAP / ours = {colmap_cpu / max(ours_cpu, 1e-9):.1f}x "
          f"summed per-plate time, {colmap_wall / max(ours_wall, 1e-9):.1f}x wall")
    (work / "results.json").write_text(json.dumps(rows, indent=1))
    for line in sorted(set(MISSING_OPTIONS)):
        print(line)
    print(f"results: {work / 'results.json'}")


if __name__ == "__main__":
    main()
