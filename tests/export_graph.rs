//! `graphs/book_export.yaml` end to end: one run writes every format, byte for byte the same
//! as a one-thread run's in another folder (reports carry no timings); the COLMAP
//! output reads back equal to the solve within 1e-9; and the real clients (pycolmap, bpy,
//! usd-core, when installed; see crates/nodes/tests/export_clients.rs) project the exported
//! points where our cameras do.

use std::fs;
use std::path::Path;
use std::process::Command;

use serde_json::json;
use vfxgraph_exchange::colmap;
use vfxgraph_geometry::camera::Camera;
use vfxgraph_testdata::{repo, Python};

/// The Python with the clients these checks use.
fn python() -> Python {
    Python::from_env(
        "VFXGRAPH_PYTHON",
        "python3",
        "pip install pycolmap bpy usd-core, or set VFXGRAPH_PYTHON",
    )
}

fn check(script: &str, export: &Path, truth: &Path, extra: &[&str]) {
    let out = python()
        .command()
        .arg(repo().join("scripts/check").join(script))
        .arg(export)
        .arg(truth)
        .args(extra)
        .output()
        .expect("run python");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    for l in text.lines().filter(|l| l.contains("->")) {
        eprintln!("{script}: {l}");
    }
    assert!(out.status.success(), "{script} failed:\n{text}");
}

#[test]
fn book_export_graph_writes_every_format_and_the_clients_agree() {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("graphs");
    if vfxgraph_testdata::graph_with_data(&repo().join("graphs/book_export.yaml"), &g).is_none() {
        return;
    }
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(&g)
        .args(["run", "--json", "book_export.yaml"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let o = g.join("out/book_export");
    // The same graph on one thread, in another folder with its own cache: the same bytes
    // (what makes a farm's outputs a local run's).
    let g1 = tmp.path().join("one_thread");
    vfxgraph_testdata::graph_with_data(&repo().join("graphs/book_export.yaml"), &g1).unwrap();
    let out1 = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(&g1)
        .args(["run", "-q", "--jobs", "1", "book_export.yaml"])
        .output()
        .unwrap();
    assert!(
        out1.status.success(),
        "{}",
        String::from_utf8_lossy(&out1.stderr)
    );
    let files = |root: &Path| {
        let mut v = Vec::new();
        let mut stack = vec![root.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    v.push((
                        p.strip_prefix(root).unwrap().to_path_buf(),
                        fs::read(&p).unwrap(),
                    ));
                }
            }
        }
        v.sort();
        v
    };
    let (a, b) = (files(&o), files(&g1.join("out/book_export")));
    assert_eq!(
        a.iter().map(|f| &f.0).collect::<Vec<_>>(),
        b.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{} differs between the two runs", name.display());
    }
    for f in [
        "colmap/cameras.txt",
        "colmap/images.txt",
        "colmap/points3D.txt",
        "book_camera.py",
        "book_camera.usda",
        "book_camera.chan",
        "book_camera_filmback.txt",
        "book_cameras.json",
        "book_points.ply",
        "relax_report.json",
    ] {
        assert!(o.join(f).is_file(), "{f} written");
    }

    // The COLMAP model and the JSON export hold the same solve: K, every pose within 1e-9
    // (R through COLMAP's quaternion), the tracks' 2-D points, and the book's K from g7cam.txt.
    let ours = colmap::read(&o.join("colmap/cameras.txt")).unwrap();
    let k = vfxgraph_geometry::formats::read_intrinsics(&vfxgraph_testdata::require(
        "book-demo/g7cam.txt",
    ))
    .unwrap()
    .with_size(1280, 720);
    assert_eq!(ours.intrinsics, k);
    let doc: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(o.join("book_cameras.json")).unwrap()).unwrap();
    let jframes = doc["frames"].as_array().unwrap();
    assert_eq!(ours.path.frames.len(), jframes.len());
    assert!(
        jframes.len() > 200,
        "the matchmove solves most of the 286 frames"
    );
    let m3 = |a: &serde_json::Value| nalgebra::Matrix3::from_fn(|r, c| a[r][c].as_f64().unwrap());
    for (a, j) in ours.path.frames.iter().zip(jframes) {
        assert_eq!(a.frame as u64, j["frame"].as_u64().unwrap());
        assert!((a.pose.r - m3(&j["R"])).abs().max() < 1e-9);
        let t = nalgebra::Vector3::from_fn(|i, _| j["t"][i].as_f64().unwrap());
        assert!((a.pose.t - t).abs().max() < 1e-9);
        assert!(j["rms_px"].is_f64() && j["observations"].as_u64().unwrap() > 0);
    }

    // Exports claim only what the solve believes: per frame, the JSON's observations are the
    // relaxation's inliers (its report's count), its RMS is theirs, and the COLMAP model links
    // exactly those observations (the rest are unassigned 2-D points).
    let report: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(o.join("relax_report.json")).unwrap()).unwrap();
    let rframes = report["frames"].as_array().unwrap();
    let images = fs::read_to_string(o.join("colmap/images.txt")).unwrap();
    let point_lines: Vec<&str> = images
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .step_by(2)
        .collect();
    assert_eq!(point_lines.len(), jframes.len());
    let (mut linked, mut rejected) = (0, 0);
    for ((j, r), line) in jframes.iter().zip(rframes).zip(&point_lines) {
        assert_eq!(j["frame"], r["frame"]);
        assert_eq!(j["observations"], r["inliers"], "frame {}", j["frame"]);
        let ids: Vec<&str> = line.split(' ').skip(2).step_by(3).collect();
        let kept = ids.iter().filter(|id| **id != "-1").count();
        assert_eq!(kept as u64, j["observations"].as_u64().unwrap());
        assert_eq!((ids.len() - kept) as u64, j["outliers"].as_u64().unwrap());
        linked += kept;
        rejected += ids.len() - kept;
        if let (Some(a), Some(b)) = (j["rms_px"].as_f64(), r["rms"].as_f64()) {
            assert!((a - b).abs() < 1e-9, "frame {}: {a} vs {b}", j["frame"]);
        }
    }
    eprintln!("book export: {linked} observations linked, {rejected} rejected by the solve");
    assert!(
        rejected > 0,
        "the book's tracks have observations the solve rejects"
    );
    assert!(!ours.cloud.points.is_empty());
    let solve = ours;

    // Our reprojections of the solve, and the graph's scene options (fps 24, frame 0 → 1).
    let frames: Vec<_> = solve
        .path
        .frames
        .iter()
        .map(|f| {
            let cam = Camera {
                intrinsics: k.clone(),
                pose: f.pose.clone(),
            };
            let px: Vec<_> = solve
                .cloud
                .points
                .iter()
                .map(|p| {
                    let p = nalgebra::Point3::new(p[0], p[1], p[2]);
                    match cam.project(&p) {
                        Ok(x) if cam.depth(&p) > 0.0 => json!([x.x, x.y]),
                        _ => serde_json::Value::Null,
                    }
                })
                .collect();
            json!({"frame": f.frame, "target_frame": f.frame as i64 + 1, "pixels": px})
        })
        .collect();
    let truth = o.join("truth.json");
    fs::write(
        &truth,
        json!({"width": 1280, "height": 720, "fps": 24.0, "start_frame": 1, "plate": false,
               "frames": frames})
        .to_string(),
    )
    .unwrap();
    // The solve's own inlier decision: every observation linked to a point is within the
    // relaxation's final tolerance in pycolmap too (+ the 1e-6 px by which pycolmap's
    // projections may differ from ours, checked above).
    let tol = (report["inlier_tolerance"].as_f64().unwrap() + 1e-6).to_string();
    if python().has("pycolmap") {
        check(
            "colmap_check.py",
            &o.join("colmap"),
            &truth,
            &["--obs-tol", &tol],
        );
    }
    if python().has("bpy") {
        check("blender_check.py", &o.join("book_camera.py"), &truth, &[]);
    }
    if python().has("pxr.Usd") {
        check("usd_check.py", &o.join("book_camera.usda"), &truth, &[]);
    }
}
