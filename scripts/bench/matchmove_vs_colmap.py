#!/usr/bin/env python3
"""Matchmove benchmark: vfxgraph (KLT tracking + matchmove solve) against COLMAP (pycolmap).

What it measures
----------------
On the 48-frame hand-held plate of ``blender_plate_dev`` (960x540, Blender Cycles at 32 spp, so
strong per-frame grain; JPEG q95) with the lens's K known and held fixed, the script runs in one go

1. COLMAP through pycolmap (tested with 4.2.1): SIFT extraction (single PINHOLE camera with the known
   K), sequential matching (overlap 10, loop detection off), incremental mapping with focal length,
   principal point and extra parameters fixed (in bundle adjustment and in absolute-pose
   registration). Each stage (features, matching, mapping) is timed with ``time.perf_counter``.
2. vfxgraph: ``vfxgraph run <graph> --cache <empty dir>`` (default graph
   ``graphs/dev_plate_solve.yaml``), timed as a whole from an empty cache (reading the JPEGs,
   tracking, solving), once with the graph's defaults and once with ``--set track.features=300``.
   The graph writes its cameras next to itself (``graphs/out/dev_plate_solve/cameras.json``); the
   script copies each run's cameras into ``--work``.
3. Both against the renderer's ground truth (``cameras_gt.json``) with the project's metric (as
   ``aligned_errors`` in ``crates/vision/src/matchmove/tests.rs``): the estimated path is aligned to
   the truth by a similarity -- the rotation R_a = nearest rotation (SVD, det +1) to
   sum_f R_truth_f^T R_est_f, then scale and translation by least squares on the camera centres
   C = -R^T t after rotating the estimated ones by R_a. Per frame: rotation error = angle between
   R_est_f R_a^T and R_truth_f (degrees), centre error = |s R_a C_est + t - C_truth| as a
   percentage of the truth path length (sum of distances between consecutive truth centres).
   COLMAP may register fewer than all frames: its errors are over the registered frames only (the
   alignment too), and the table says how many.

It prints one table (frames registered, rotation max/mean, centre max/mean, time per stage and
total) with the speed ratio COLMAP_total / vfxgraph_total and the error ratios, and writes
everything as JSON (``--work``/results.json unless ``--results`` is given).

Pixel convention
----------------
vfxgraph and the truth put pixel (0, 0) at the *centre* of the top-left pixel (cx = 479.5,
cy = 269.5 for this plate); COLMAP puts it at the top-left *corner*, so the same K is given to COLMAP
as cx = 480.0, cy = 270.0 (+0.5 px). Rotations and camera centres do not depend on this once K is
converted.

How to run
----------
From the repository root, with the python that has pycolmap (and numpy)::

    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/matchmove_vs_colmap.py

Options: ``--plate-dir``, ``--truth``, ``--vfxgraph`` (binary; default ``vfxgraph`` on PATH, else
``target/release/vfxgraph``), ``--graph``, ``--threads`` (default 2, given to COLMAP's stages and
as ``-j`` to vfxgraph), ``--work`` (default a fresh temporary folder), ``--skip-colmap`` /
``--skip-vfxgraph``, ``--features`` (the vfxgraph variants, default ``default,300``).
"""

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent.parent
DEFAULT_PLATE = Path("/work/shared/data/blender_plate_dev/pinhole/plate")

# The plate's K in vfxgraph's convention (pixel (0,0) = centre of the top-left pixel).
FX = FY = 920.0
CX, CY = 479.5, 269.5
COLMAP_PIXEL_SHIFT = 0.5  # COLMAP: pixel (0,0) = top-left corner


# --------------------------------------------------------------------------------------------
# Error metric (the project's aligned_errors)
# --------------------------------------------------------------------------------------------

def nearest_rotation(m):
    u, _, vt = np.linalg.svd(m)
    d = np.eye(3)
    if np.linalg.det(u @ vt) < 0:
        d[2, 2] = -1.0
    return u @ d @ vt


def rotation_angle_deg(a, b):
    """Angle of a b^T (atan2 of its sine and cosine: accurate for small angles too)."""
    m = a @ b.T
    sin = 0.5 * np.linalg.norm([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    cos = 0.5 * (np.trace(m) - 1.0)
    return float(np.degrees(np.arctan2(sin, cos)))


def centre(r, t):
    return -r.T @ t


def aligned_errors(est, truth):
    """est, truth: lists of (R, t) world-to-camera for the same frames. Returns per-frame
    rotation errors (degrees) and centre errors (scene units)."""
    m = np.zeros((3, 3))
    for (re_, _), (rg, _) in zip(est, truth):
        m += rg.T @ re_
    ra = nearest_rotation(m)
    a = np.array([ra @ centre(r, t) for r, t in est])
    b = np.array([centre(r, t) for r, t in truth])
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    s = float(((a - ma) * (b - mb)).sum() / ((a - ma) ** 2).sum())
    rot = [rotation_angle_deg(re_ @ ra.T, rg) for (re_, _), (rg, _) in zip(est, truth)]
    cen = np.linalg.norm(s * (a - ma) + mb - b, axis=1).tolist()
    return rot, cen


def path_length(truth_by_frame):
    fs = sorted(truth_by_frame)
    cs = [centre(*truth_by_frame[f]) for f in fs]
    return float(sum(np.linalg.norm(cs[i + 1] - cs[i]) for i in range(len(cs) - 1)))


def load_cameras_json(path):
    """{"frames": [{"frame", "R", "t"}, ...]} -> {frame: (R, t)}."""
    d = json.loads(Path(path).read_text())
    return {int(f["frame"]): (np.array(f["R"], float), np.array(f["t"], float))
            for f in d["frames"]}


def evaluate(est_by_frame, truth_by_frame, nframes):
    frames = sorted(f for f in est_by_frame if f in truth_by_frame)
    if len(frames) < 3:
        return {"frames_registered": len(frames), "frames_total": nframes,
                "error": "fewer than 3 frames registered"}
    est = [est_by_frame[f] for f in frames]
    tru = [truth_by_frame[f] for f in frames]
    rot, cen = aligned_errors(est, tru)
    length = path_length(truth_by_frame)  # the whole truth path, as the project's tests
    cen_pct = [100.0 * c / length for c in cen]
    missing = [f for f in sorted(truth_by_frame) if f not in est_by_frame]
    return {
        "frames_registered": len(frames),
        "frames_total": nframes,
        "frames_missing": missing,
        "rot_max_deg": max(rot),
        "rot_mean_deg": float(np.mean(rot)),
        "centre_max_pct": max(cen_pct),
        "centre_mean_pct": float(np.mean(cen_pct)),
        "truth_path_length": length,
        "per_frame": [{"frame": f, "rot_deg": r, "centre_pct": c}
                      for f, r, c in zip(frames, rot, cen_pct)],
    }


# --------------------------------------------------------------------------------------------
# COLMAP
# --------------------------------------------------------------------------------------------

FRAME_RE = re.compile(r"(\d+)(?=\.[^.]+$)")


def frame_of(name):
    m = FRAME_RE.search(name)
    if not m:
        raise ValueError(f"no frame number in image name {name!r}")
    return int(m.group(1))


def set_if(obj, name, value, log):
    if hasattr(obj, name):
        setattr(obj, name, value)
    else:
        log.append(f"option {type(obj).__name__}.{name} not present in this pycolmap")


def run_colmap(plate_dir, work, threads, log):
    import pycolmap

    work = Path(work) / "colmap"
    if work.exists():
        shutil.rmtree(work)
    (work / "sparse").mkdir(parents=True)
    db = work / "database.db"
    names = sorted(p.name for p in Path(plate_dir).iterdir()
                   if p.suffix.lower() in (".jpg", ".jpeg", ".png"))

    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.camera_params = ",".join(str(v) for v in (
        FX, FY, CX + COLMAP_PIXEL_SHIFT, CY + COLMAP_PIXEL_SHIFT))
    extraction = pycolmap.FeatureExtractionOptions()
    set_if(extraction, "num_threads", threads, log)
    set_if(extraction, "use_gpu", False, log)

    times, cpu = {}, {}
    c0, t0 = time.process_time(), time.perf_counter()
    pycolmap.extract_features(db, plate_dir, image_names=names,
                              camera_mode=pycolmap.CameraMode.SINGLE,
                              reader_options=reader, extraction_options=extraction,
                              device=pycolmap.Device.cpu)
    times["features"] = time.perf_counter() - t0
    cpu["features"] = time.process_time() - c0

    matching = pycolmap.FeatureMatchingOptions()
    set_if(matching, "num_threads", threads, log)
    set_if(matching, "use_gpu", False, log)
    pairing = pycolmap.SequentialPairingOptions()
    pairing.overlap = 10
    pairing.loop_detection = False
    set_if(pairing, "num_threads", threads, log)
    c0, t0 = time.process_time(), time.perf_counter()
    pycolmap.match_sequential(db, matching_options=matching, pairing_options=pairing,
                              device=pycolmap.Device.cpu)
    times["matching"] = time.perf_counter() - t0
    cpu["matching"] = time.process_time() - c0

    opts = pycolmap.IncrementalPipelineOptions()
    opts.num_threads = threads
    opts.ba_refine_focal_length = False
    opts.ba_refine_principal_point = False
    opts.ba_refine_extra_params = False
    opts.random_seed = 1
    mapper = opts.mapper
    set_if(mapper, "abs_pose_refine_focal_length", False, log)
    set_if(mapper, "abs_pose_refine_extra_params", False, log)
    set_if(mapper, "num_threads", threads, log)
    set_if(mapper, "random_seed", 1, log)
    opts.mapper = mapper
    c0, t0 = time.process_time(), time.perf_counter()
    recs = pycolmap.incremental_mapping(db, plate_dir, work / "sparse", options=opts)
    times["mapping"] = time.perf_counter() - t0
    cpu["mapping"] = time.process_time() - c0
    times["total"] = times["features"] + times["matching"] + times["mapping"]
    cpu["total"] = cpu["features"] + cpu["matching"] + cpu["mapping"]

    models = {int(k): r.num_reg_images() for k, r in recs.items()}
    if not recs:
        return {"times": times, "cpu": cpu, "models": models, "cameras": {}, "names": names}
    best = max(recs, key=lambda k: recs[k].num_reg_images())
    rec = recs[best]
    cams = {}
    for img in rec.images.values():
        if hasattr(img, "has_pose") and not img.has_pose:
            continue
        p = img.cam_from_world
        p = p() if callable(p) else p
        cams[frame_of(img.name)] = (np.array(p.rotation.matrix(), float),
                                    np.array(p.translation, float).reshape(3))
    cam = next(iter(rec.cameras.values()))
    return {
        "times": times,
        "cpu": cpu,
        "models": models,
        "model_used": int(best),
        "camera_params_after": [float(v) for v in cam.params],
        "num_points3D": int(rec.num_points3D()),
        "mean_reprojection_error_px": float(rec.compute_mean_reprojection_error()),
        "cameras": cams,
        "names": names,
    }


# --------------------------------------------------------------------------------------------
# vfxgraph
# --------------------------------------------------------------------------------------------

def find_vfxgraph(arg):
    if arg:
        return arg
    on_path = shutil.which("vfxgraph")
    if on_path:
        return on_path
    return str(REPO / "target" / "release" / "vfxgraph")


def cameras_output_of(graph):
    """The path of the graph's write_cameras node (relative to the graph's folder)."""
    lines = Path(graph).read_text().splitlines()
    for i, line in enumerate(lines):
        if re.match(r"\s*type:\s*write_cameras\s*$", line):
            for nxt in lines[i + 1:i + 6]:
                m = re.search(r"path:\s*\"?([^\",}]+)\"?", nxt)
                if m:
                    return Path(graph).resolve().parent / m.group(1).strip()
    return Path(graph).resolve().parent / "out" / Path(graph).stem / "cameras.json"


def run_vfxgraph(binary, graph, work, threads, features, log):
    tag = "default" if features in (None, "default") else f"features{features}"
    cache = Path(work) / f"vfxgraph_cache_{tag}"
    if cache.exists():
        shutil.rmtree(cache)
    cache.mkdir(parents=True)
    out = cameras_output_of(graph)
    if out.exists():
        out.unlink()  # so a failed run can't be scored on a stale file
    cmd = [binary, "run", str(graph), "--cache", str(cache), "-j", str(threads), "-q"]
    if tag != "default":
        cmd += ["--set", f"track.features={features}"]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    total = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_total = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    res = {"label": f"vfxgraph ({'features=150 default' if tag == 'default' else 'features=' + str(features)})",
           "command": " ".join(cmd), "returncode": proc.returncode,
           "times": {"total": total}, "cpu": {"total": cpu_total}}
    if proc.returncode != 0 or not out.exists():
        res["stderr"] = proc.stderr[-4000:]
        log.append(f"vfxgraph {tag} failed (rc {proc.returncode}): {proc.stderr[-500:]}")
        res["cameras"] = {}
        return res
    kept = Path(work) / f"vfxgraph_cameras_{tag}.json"
    shutil.copyfile(out, kept)
    res["cameras_json"] = str(kept)
    res["cameras"] = load_cameras_json(kept)
    return res


# --------------------------------------------------------------------------------------------

def fmt(v, spec):
    if v is None:
        width = re.match(r"\d*", spec).group(0)
        return format("-", ">" + width) if width else "-"
    return format(v, spec)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plate-dir", default=str(DEFAULT_PLATE))
    ap.add_argument("--truth", default=None,
                    help="cameras_gt.json (default: beside the plate folder)")
    ap.add_argument("--vfxgraph", default=None)
    ap.add_argument("--graph", default=str(REPO / "graphs" / "dev_plate_solve.yaml"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default=None)
    ap.add_argument("--results", default=None, help="results JSON (default WORK/results.json)")
    ap.add_argument("--features", default="default,300",
                    help="vfxgraph track.features variants, comma-separated ('default' = graph's)")
    ap.add_argument("--skip-colmap", action="store_true")
    ap.add_argument("--skip-vfxgraph", action="store_true")
    args = ap.parse_args()

    plate = Path(args.plate_dir).resolve()
    truth_path = Path(args.truth) if args.truth else plate.parent / "cameras_gt.json"
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="mm_vs_colmap_"))
    work.mkdir(parents=True, exist_ok=True)
    results_path = Path(args.results) if args.results else work / "results.json"
    graph = Path(args.graph)
    if not graph.is_absolute() and not graph.exists() and (REPO / graph).exists():
        graph = REPO / graph  # relative to the repository root
    if not args.skip_vfxgraph and not graph.exists():
        sys.exit(f"graph {graph} not found (--graph)")
    args.graph = str(graph.resolve())
    truth = load_cameras_json(truth_path)
    gt = json.loads(truth_path.read_text())
    k = np.array(gt["K"], float)
    if not np.allclose(k, [[FX, 0, CX], [0, FY, CY], [0, 0, 1]]):
        sys.exit(f"truth K {k.tolist()} differs from the K this script gives COLMAP")
    nframes = len(truth)
    log = []

    def load():
        try:
            return os.getloadavg()
        except OSError:
            return None

    rows = []
    meta = {"plate_dir": str(plate), "truth": str(truth_path), "graph": str(args.graph),
            "threads": args.threads, "work": str(work), "cpu_count": os.cpu_count(),
            "loadavg_start": load(), "argv": sys.argv}

    if not args.skip_colmap:
        import pycolmap
        meta["pycolmap_version"] = pycolmap.__version__
        print(f"COLMAP (pycolmap {pycolmap.__version__}) on {plate} ...", flush=True)
        c = run_colmap(str(plate), work, args.threads, log)
        row = {"tool": "COLMAP", "label": f"COLMAP (pycolmap {pycolmap.__version__})",
               "times": c["times"], "cpu": c["cpu"], "models": c["models"],
               **{k_: c[k_] for k_ in ("model_used", "camera_params_after", "num_points3D",
                                       "mean_reprojection_error_px") if k_ in c}}
        row.update(evaluate(c["cameras"], truth, nframes))
        rows.append(row)
        meta["loadavg_after_colmap"] = load()

    if not args.skip_vfxgraph:
        binary = find_vfxgraph(args.vfxgraph)
        for feat in [f.strip() for f in args.features.split(",") if f.strip()]:
            print(f"vfxgraph ({feat}) ...", flush=True)
            v = run_vfxgraph(binary, args.graph, work, args.threads, feat, log)
            row = {"tool": "vfxgraph", **{k_: v[k_] for k_ in v if k_ != "cameras"}}
            row.update(evaluate(v["cameras"], truth, nframes))
            rows.append(row)
    meta["loadavg_end"] = load()

    # ---- table
    head = (f"{'tool':34} {'frames':>7} {'rot max':>8} {'rot mean':>8} {'C max':>7} "
            f"{'C mean':>7} {'feat s':>7} {'match s':>7} {'map s':>7} {'total s':>8} "
            f"{'CPU s':>7}")
    print()
    print("rotation errors in degrees, centre errors C in % of the truth path length; "
          "errors over the registered frames; times are wall clock (perf_counter), CPU s = "
          "user+system CPU time of the process (COLMAP) / child process (vfxgraph)")
    print(head)
    print("-" * len(head))
    for r in rows:
        t = r["times"]
        print(f"{r['label']:34} {r['frames_registered']:>3}/{r['frames_total']:<3} "
              f"{fmt(r.get('rot_max_deg'), '8.3f')} {fmt(r.get('rot_mean_deg'), '8.3f')} "
              f"{fmt(r.get('centre_max_pct'), '7.3f')} {fmt(r.get('centre_mean_pct'), '7.3f')} "
              f"{fmt(t.get('features'), '7.1f')} {fmt(t.get('matching'), '7.1f')} "
              f"{fmt(t.get('mapping'), '7.1f')} {fmt(t.get('total'), '8.1f')} "
              f"{fmt(r['cpu'].get('total'), '7.1f')}")
    ratios = []
    col = next((r for r in rows if r["tool"] == "COLMAP"), None)
    for r in rows:
        if col is None or r["tool"] != "vfxgraph" or "rot_max_deg" not in r \
                or "rot_max_deg" not in col:
            continue
        q = {"vs": r["label"],
             "speed_colmap_over_vfxgraph": col["times"]["total"] / r["times"]["total"],
             "cpu_colmap_over_vfxgraph": col["cpu"]["total"] / r["cpu"]["total"]}
        for key in ("rot_max_deg", "rot_mean_deg", "centre_max_pct", "centre_mean_pct"):
            q[f"{key}_colmap_over_vfxgraph"] = col[key] / r[key] if r[key] > 0 else None
        ratios.append(q)
        print(f"COLMAP / {r['label']}: wall time x{q['speed_colmap_over_vfxgraph']:.2f}, "
              f"CPU time x{q['cpu_colmap_over_vfxgraph']:.2f}; errors "
              f"rot max x{fmt(q['rot_max_deg_colmap_over_vfxgraph'], '.2f')}, "
              f"rot mean x{fmt(q['rot_mean_deg_colmap_over_vfxgraph'], '.2f')}, "
              f"C max x{fmt(q['centre_max_pct_colmap_over_vfxgraph'], '.2f')}, "
              f"C mean x{fmt(q['centre_mean_pct_colmap_over_vfxgraph'], '.2f')}")
    if col is not None:
        print(f"COLMAP models (id: registered images): {col['models']}; "
              f"camera after mapping {col.get('camera_params_after')}; "
              f"{col.get('num_points3D')} points, "
              f"mean reprojection error {fmt(col.get('mean_reprojection_error_px'), '.3f')} px"
              + (f"; frames missing {col['frames_missing']}" if col.get("frames_missing") else ""))
    la = meta["loadavg_start"], meta["loadavg_end"]
    print(f"threads {args.threads} on {meta['cpu_count']} cores; load average (1, 5, 15 min) "
          f"at start {la[0]}, at end {la[1]}")
    for line in log:
        print("note:", line)

    results_path.parent.mkdir(parents=True, exist_ok=True)
    results_path.write_text(json.dumps({"meta": meta, "rows": rows, "ratios": ratios,
                                        "notes": log}, indent=1))
    print(f"results: {results_path}")


if __name__ == "__main__":
    main()
