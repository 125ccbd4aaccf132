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
   ``aligned_errors`` in ``crates/matchmove/src/tests.rs``): the estimated path is aligned to
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

Unknown lens (``--lens unknown``)
---------------------------------
The same comparison on the *distorted* plate (``blender_plate_dev/distorted``: the same 48 frames
through a Brown-Conrady lens, f = 920 px, k1 = -0.16, k2 = 0.045, p1 = 0.0008, p2 = -0.0005, about
30 px at the corners), with neither tool given K or the distortion:

- COLMAP: one shared camera of model ``RADIAL`` (f, cx, cy, k1, k2; ``--colmap-model OPENCV`` for
  fx, fy, cx, cy, k1, k2, p1, p2), its parameters left to COLMAP's own no-EXIF default (the JPEGs
  have no EXIF): f = ``default_focal_length_factor`` (1.2) x max(w, h) = 1152 px, principal point
  at the image centre, distortion 0, no focal prior. Bundle adjustment and absolute-pose
  registration refine the focal length and the extra (distortion) parameters; the principal point
  stays fixed at the centre, which is the true one (COLMAP's (480, 270) = our (479.5, 269.5)).
  Matching, pairing and the rest of the mapping as above.
- vfxgraph: ``graphs/dev_plate_lens.yaml`` (``focal: unknown, distortion: k1k2``): it estimates
  the focal length from the tracks and refines f, k1, k2 in its bundle adjustment. In this mode the
  graph's outputs (cameras, report) are redirected into ``--work`` with ``--set`` so the run leaves
  ``graphs/out`` alone; the solved K and lens are read from its cameras.json, the initial focal
  length from the report's notes.

Both tools' k1, k2 act on normalized coordinates (x/z, y/z), as OpenCV's and the truth's, so they
compare directly. Errors are measured as above (the metric does not use K); a second table gives
each tool's solved lens: f (px and % error vs 920; for OPENCV the mean of fx and fy), k1, k2 (and
p1, p2 when the model has them), the principal point in our convention, and the initial focal.

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
    ~/.cache/vfxgraph/pyenv-export/bin/python scripts/bench/matchmove_vs_colmap.py --lens unknown

Options: ``--lens known|unknown`` (default known: the pinhole plate with K fixed, as described
first), ``--colmap-model RADIAL|OPENCV`` (unknown lens only; default RADIAL), ``--plate-dir``
(default per ``--lens``), ``--truth``, ``--vfxgraph`` (binary; default ``vfxgraph`` on PATH, else
``target/release/vfxgraph``), ``--graph`` (default per ``--lens``), ``--threads`` (default 2, given
to COLMAP's stages and as ``-j`` to vfxgraph), ``--work`` (default a fresh temporary folder),
``--skip-colmap`` / ``--skip-vfxgraph``, ``--features`` (the vfxgraph variants, default
``default,300``).
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
DATA = Path("/work/shared/data/blender_plate_dev")
DEFAULT_PLATE = DATA / "pinhole" / "plate"
DEFAULT_GRAPH = REPO / "graphs" / "dev_plate_solve.yaml"
# --lens unknown: the distorted plate, solved without K or distortion.
DISTORTED_PLATE = DATA / "distorted" / "plate"
LENS_GRAPH = REPO / "graphs" / "dev_plate_lens.yaml"
COLMAP_LENS_MODELS = ("RADIAL", "OPENCV")

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


def lens_of_colmap_camera(cam):
    """A COLMAP camera -> the lens in our convention (principal point -0.5 px)."""
    model = str(cam.model_name)
    p = [float(v) for v in cam.params]
    if model == "RADIAL":  # f, cx, cy, k1, k2
        lens = {"fx": p[0], "fy": p[0], "cx": p[1], "cy": p[2], "k1": p[3], "k2": p[4]}
    elif model == "OPENCV":  # fx, fy, cx, cy, k1, k2, p1, p2
        lens = {"fx": p[0], "fy": p[1], "cx": p[2], "cy": p[3], "k1": p[4], "k2": p[5],
                "p1": p[6], "p2": p[7]}
    elif model == "PINHOLE":
        lens = {"fx": p[0], "fy": p[1], "cx": p[2], "cy": p[3], "k1": 0.0, "k2": 0.0}
    else:
        return {"model": model, "params": p}
    lens["cx"] -= COLMAP_PIXEL_SHIFT
    lens["cy"] -= COLMAP_PIXEL_SHIFT
    lens["f"] = 0.5 * (lens["fx"] + lens["fy"])
    lens["model"] = model
    return lens


def run_colmap(plate_dir, work, threads, log, lens="known", model="RADIAL", known_camera=None,
               zoom=False):
    """lens "known": PINHOLE with the plate's K, fixed (or `known_camera`: a COLMAP model name
    and its parameters, e.g. RADIAL f, cx, cy, k1, k2 for a known lens, fixed too). lens
    "unknown": one shared camera of `model` with COLMAP's no-EXIF default parameters; focal
    length and distortion refined. `zoom`: a camera per image, each starting from the known
    one, its focal length refined (the distortion held)."""
    import pycolmap

    work = Path(work) / "colmap"
    if work.exists():
        shutil.rmtree(work)
    (work / "sparse").mkdir(parents=True)
    db = work / "database.db"
    names = sorted(p.name for p in Path(plate_dir).iterdir()
                   if p.suffix.lower() in (".jpg", ".jpeg", ".png"))

    reader = pycolmap.ImageReaderOptions()
    if lens == "known" and known_camera:
        reader.camera_model = known_camera[0]
        reader.camera_params = ",".join(str(v) for v in known_camera[1])
    elif lens == "known":
        reader.camera_model = "PINHOLE"
        reader.camera_params = ",".join(str(v) for v in (
            FX, FY, CX + COLMAP_PIXEL_SHIFT, CY + COLMAP_PIXEL_SHIFT))
    else:
        # Empty camera_params: COLMAP's own guess (f = default_focal_length_factor * max(w, h)
        # unless EXIF gives one, principal point at the centre, distortion 0).
        reader.camera_model = model
        reader.camera_params = ""
    extraction = pycolmap.FeatureExtractionOptions()
    set_if(extraction, "num_threads", threads, log)
    set_if(extraction, "use_gpu", False, log)

    times, cpu = {}, {}
    c0, t0 = time.process_time(), time.perf_counter()
    pycolmap.extract_features(db, plate_dir, image_names=names,
                              camera_mode=(pycolmap.CameraMode.PER_IMAGE if zoom
                                           else pycolmap.CameraMode.SINGLE),
                              reader_options=reader, extraction_options=extraction,
                              device=pycolmap.Device.cpu)
    times["features"] = time.perf_counter() - t0
    cpu["features"] = time.process_time() - c0
    initial = None
    if lens != "known":
        db_ = pycolmap.Database.open(db)
        cams0 = db_.read_all_cameras()
        db_.close()
        if len(cams0) != 1:
            log.append(f"COLMAP database has {len(cams0)} cameras (expected 1 shared)")
        if cams0:
            initial = {**lens_of_colmap_camera(cams0[0]),
                       "has_prior_focal_length": bool(cams0[0].has_prior_focal_length)}

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

    refine = lens != "known"  # focal length and distortion; the principal point never
    opts = pycolmap.IncrementalPipelineOptions()
    opts.num_threads = threads
    opts.ba_refine_focal_length = refine or zoom
    opts.ba_refine_principal_point = False
    opts.ba_refine_extra_params = refine
    opts.random_seed = 1
    mapper = opts.mapper
    set_if(mapper, "abs_pose_refine_focal_length", refine or zoom, log)
    set_if(mapper, "abs_pose_refine_extra_params", refine, log)
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
        return {"times": times, "cpu": cpu, "models": models, "cameras": {}, "names": names,
                **({"lens_initial": initial} if initial else {})}
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
    out = {
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
    if lens != "known":
        out["lens"] = lens_of_colmap_camera(cam)
        out["lens_initial"] = initial
    return out


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


def output_nodes_of(graph):
    """{node: (type, path)} of the graph's write_*/plot_* nodes that have a path param (a plain
    reading of the YAML layout the repository's graphs use: nodes at 2 spaces, fields at 4)."""
    nodes, name = {}, None
    for line in Path(graph).read_text().splitlines():
        m = re.match(r"  (\w+):\s*$", line)
        if m:
            name, kind = m.group(1), None
            continue
        if name is None or not line.startswith("    "):
            if not line.startswith(" "):
                name = None
            continue
        m = re.match(r"\s*type:\s*(\w+)\s*$", line)
        if m:
            kind = m.group(1)
        m = re.search(r"\bpath:\s*\"?([^\",}]+)\"?", line)
        if m and kind and (kind.startswith("write_") or kind.startswith("plot_")):
            nodes[name] = (kind, m.group(1).strip())
    return nodes


def lens_of_vfxgraph(cameras_json, report_json):
    """The solved K and lens from the graph's cameras.json (our convention), and the initial
    focal length from its report's notes when present."""
    d = json.loads(Path(cameras_json).read_text())
    intr = d.get("intrinsics") or {}
    if "K" not in intr:
        return None
    k = intr["K"]
    dist = intr.get("distortion") or {}
    lens = {"model": dist.get("model", "pinhole"), "fx": float(k[0][0]), "fy": float(k[1][1]),
            "cx": float(k[0][2]), "cy": float(k[1][2])}
    lens["f"] = 0.5 * (lens["fx"] + lens["fy"])
    for key in ("k1", "k2", "k3", "p1", "p2"):
        if key in dist:
            lens[key] = float(dist[key])
    if report_json and Path(report_json).exists():
        notes = json.loads(Path(report_json).read_text()).get("notes") or []
        for note in notes:
            m = re.search(r"initial focal length ([0-9.]+) px", str(note))
            if m:
                lens["f_initial"] = float(m.group(1))
        lens["notes"] = notes
    return lens


def run_vfxgraph(binary, graph, work, threads, features, log, redirect_outputs=False):
    """redirect_outputs: --set each write_*/plot_* node's path into WORK/vfxgraph_out_<tag>/
    (else the graph writes next to itself, under graphs/out)."""
    tag = "default" if features in (None, "default") else f"features{features}"
    cache = Path(work) / f"vfxgraph_cache_{tag}"
    if cache.exists():
        shutil.rmtree(cache)
    cache.mkdir(parents=True)
    out = cameras_output_of(graph)
    sets, report = [], None
    if redirect_outputs:
        outdir = Path(work) / f"vfxgraph_out_{tag}"
        if outdir.exists():
            shutil.rmtree(outdir)
        outdir.mkdir(parents=True)
        for node, (kind, path) in output_nodes_of(graph).items():
            target = outdir / Path(path).name
            sets += ["--set", f"{node}.path={target}"]
            if kind == "write_cameras":
                out = target
            elif kind == "write_report":
                report = target
    if out.exists():
        out.unlink()  # so a failed run can't be scored on a stale file
    cmd = [binary, "run", str(graph), "--cache", str(cache), "-j", str(threads), "-q"] + sets
    if tag != "default":
        cmd += ["--set", f"track.features={features}"]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    total = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_total = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    res = {"label": f"vfxgraph ({'default features: one per 36×36 px' if tag == 'default' else 'features=' + str(features)})",
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
    if redirect_outputs:
        res["lens"] = lens_of_vfxgraph(kept, report)
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
    ap.add_argument("--lens", choices=("known", "unknown"), default="known",
                    help="known: pinhole plate, K given and fixed (default); unknown: distorted "
                         "plate, neither tool given K or distortion")
    ap.add_argument("--colmap-model", choices=COLMAP_LENS_MODELS, default="RADIAL",
                    help="COLMAP camera model with --lens unknown (default RADIAL)")
    ap.add_argument("--plate-dir", default=None,
                    help=f"default {DEFAULT_PLATE} (--lens known), {DISTORTED_PLATE} (unknown)")
    ap.add_argument("--truth", default=None,
                    help="cameras_gt.json (default: beside the plate folder)")
    ap.add_argument("--vfxgraph", default=None)
    ap.add_argument("--graph", default=None,
                    help=f"default {DEFAULT_GRAPH.relative_to(REPO)} (--lens known), "
                         f"{LENS_GRAPH.relative_to(REPO)} (unknown)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default=None)
    ap.add_argument("--results", default=None, help="results JSON (default WORK/results.json)")
    ap.add_argument("--features", default="default,300",
                    help="vfxgraph track.features variants, comma-separated ('default' = graph's)")
    ap.add_argument("--skip-colmap", action="store_true")
    ap.add_argument("--skip-vfxgraph", action="store_true")
    args = ap.parse_args()
    unknown = args.lens == "unknown"
    if args.plate_dir is None:
        args.plate_dir = str(DISTORTED_PLATE if unknown else DEFAULT_PLATE)
    if args.graph is None:
        args.graph = str(LENS_GRAPH if unknown else DEFAULT_GRAPH)

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
    truth_lens = {"model": "truth", "fx": float(k[0, 0]), "fy": float(k[1, 1]),
                  "cx": float(k[0, 2]), "cy": float(k[1, 2]), "f": 0.5 * float(k[0, 0] + k[1, 1]),
                  **{key: float(v) for key, v in (gt.get("distortion") or {}).items()
                     if key in ("k1", "k2", "k3", "p1", "p2")}}
    if not unknown and gt.get("distortion"):
        print(f"note: {truth_path} has a lens distortion; --lens known gives COLMAP a PINHOLE K",
              flush=True)
    nframes = len(truth)
    log = []

    def load():
        try:
            return os.getloadavg()
        except OSError:
            return None

    rows = []
    meta = {"lens": args.lens, "plate_dir": str(plate), "truth": str(truth_path),
            "graph": str(args.graph), "threads": args.threads, "work": str(work),
            "cpu_count": os.cpu_count(), "loadavg_start": load(), "argv": sys.argv}
    if unknown:
        meta["colmap_model"] = args.colmap_model
        meta["truth_lens"] = truth_lens

    if not args.skip_colmap:
        import pycolmap
        meta["pycolmap_version"] = pycolmap.__version__
        print(f"COLMAP (pycolmap {pycolmap.__version__}) on {plate} ...", flush=True)
        c = run_colmap(str(plate), work, args.threads, log, lens=args.lens,
                       model=args.colmap_model)
        label = f"COLMAP (pycolmap {pycolmap.__version__})"
        if unknown:
            label = f"COLMAP {pycolmap.__version__} {args.colmap_model}"
        row = {"tool": "COLMAP", "label": label,
               "times": c["times"], "cpu": c["cpu"], "models": c["models"],
               **{k_: c[k_] for k_ in ("model_used", "camera_params_after", "num_points3D",
                                       "mean_reprojection_error_px", "lens", "lens_initial")
                  if k_ in c}}
        row.update(evaluate(c["cameras"], truth, nframes))
        rows.append(row)
        meta["loadavg_after_colmap"] = load()

    if not args.skip_vfxgraph:
        binary = find_vfxgraph(args.vfxgraph)
        for feat in [f.strip() for f in args.features.split(",") if f.strip()]:
            print(f"vfxgraph ({feat}) ...", flush=True)
            v = run_vfxgraph(binary, args.graph, work, args.threads, feat, log,
                             redirect_outputs=unknown)
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
    if unknown:
        print()
        print("solved lens (unknown-lens mode): f in px (OPENCV: mean of fx, fy) and its error vs "
              f"the truth's {truth_lens['f']:g}; principal point in our convention (pixel-centre "
              "origin); p1, p2: - = not in the model (vfxgraph's k1k2 keeps them at 0); "
              "f init = the focal length each started from")
        lhead = (f"{'tool':34} {'f px':>8} {'f err %':>8} {'k1':>8} {'k2':>8} {'p1':>8} "
                 f"{'p2':>8} {'cx':>7} {'cy':>7} {'f init':>7}")
        print(lhead)
        print("-" * len(lhead))
        lens_rows = [{"label": "truth", "lens": truth_lens}] + rows
        for r in lens_rows:
            ln = r.get("lens") or {}
            f = ln.get("f")
            ferr = 100.0 * (f - truth_lens["f"]) / truth_lens["f"] if f is not None else None
            if r["label"] == "truth":
                finit = None
            elif r.get("tool") == "COLMAP":
                finit = (r.get("lens_initial") or {}).get("f")
            else:
                finit = ln.get("f_initial")
            print(f"{r['label']:34} {fmt(f, '8.2f')} {fmt(ferr, '+8.2f')} "
                  f"{fmt(ln.get('k1'), '8.4f')} {fmt(ln.get('k2'), '8.4f')} "
                  f"{fmt(ln.get('p1'), '8.5f')} {fmt(ln.get('p2'), '8.5f')} "
                  f"{fmt(ln.get('cx'), '7.2f')} {fmt(ln.get('cy'), '7.2f')} {fmt(finit, '7.1f')}")
            if r["label"] != "truth":
                r["focal_error_pct"] = ferr
        if col is not None and col.get("lens_initial"):
            li = col["lens_initial"]
            print(f"COLMAP's initial camera ({li.get('model')}, our convention): f {li.get('f')}, "
                  f"cx {li.get('cx')}, cy {li.get('cy')}, "
                  f"prior focal length {li.get('has_prior_focal_length')}")
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
