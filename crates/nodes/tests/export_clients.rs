//! The camera exports loaded in the real programs: pycolmap, Blender's `bpy` and
//! usd-core run the checkers of `scripts/check/` on our exports of shots with known truth, and
//! compare their projections with ours (COLMAP within 1e-6 px, Blender and USD within 0.01 px).
//! Shots through a lens (Brown–Conrady, division) check the distortion in each client: pycolmap's
//! projection of the points (its OPENCV models), USD's frustum taken through the
//! `vfxgraph:lens:*` attributes, Blender's Movie Distortion node with the script's tracking
//! camera (see the checkers' docs).
//!
//! The Python comes from `VFXGRAPH_PYTHON` (default `python3`). A test whose module is missing
//! prints a notice and passes, unless `VFXGRAPH_REQUIRE_CLIENTS=1` (set by `.ci/run`), where it
//! fails.

use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};
use serde_json::json;
use vfxgraph_exchange::files::write;
use vfxgraph_exchange::{colmap, ExportFormat, SceneOptions, Shot, UpAxis};
use vfxgraph_geometry::camera::{Camera, Intrinsics, Pose};
use vfxgraph_geometry::formats::{CameraPath, FramePose};
use vfxgraph_geometry::lens::Distortion;
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_geometry::rotation::axis_angle_to_r;
use vfxgraph_klt::{Track, Tracks};
use vfxgraph_params::Choice;
use vfxgraph_testdata::{repo, Python};

/// The Python with the clients these checks use.
fn python() -> Python {
    Python::from_env(
        "VFXGRAPH_PYTHON",
        "python3",
        "pip install pycolmap bpy usd-core, or set VFXGRAPH_PYTHON",
    )
}

/// Writes `shot` in the format named `format` (`colmap`, `blender`, `usd`, `nuke`, `json`, `ply`).
fn export(
    format: &str,
    path: &Path,
    shot: &Shot,
    o: &SceneOptions,
) -> Result<Vec<PathBuf>, vfxgraph_geometry::VisionError> {
    let f = ExportFormat::from_choice(format).expect("an export format");
    write(f, path, shot, o)
}

/// Runs a checker (with extra arguments); panics with its output unless it exits 0.
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
    // The summary lines, for the test log.
    for l in text
        .lines()
        .filter(|l| l.contains("->") || l.starts_with("FAIL"))
    {
        eprintln!("{script}: {l}");
    }
    assert!(out.status.success(), "{script} failed:\n{text}");
}

/// A 40-frame shot with known truth: the camera dollies and pans around 60 points, K as given.
fn shot(k: Intrinsics) -> Shot {
    shot_zooming(k, None)
}

/// [`shot`] with frame i's focal length `zoom(i)` when given.
fn shot_zooming(k: Intrinsics, zoom: Option<&dyn Fn(usize) -> f64>) -> Shot {
    let frames = (0..40)
        .map(|i| {
            let a = i as f64 / 39.0;
            let r = axis_angle_to_r(&Vector3::new(0.08 * (3.0 * a).sin(), 0.5 - a, 0.05));
            let c = Vector3::new(-2.0 + 4.0 * a, -0.4 + 0.2 * a, -7.0 + a);
            FramePose {
                frame: 5 + i,
                pose: Pose::new(r, -(r * c)),
                focal: zoom.map(|z| z(i)),
            }
        })
        .collect();
    let points: Vec<[f64; 3]> = (0..60)
        .map(|j| {
            let b = j as f64;
            [
                (b * 0.37).sin() * 2.0,
                (b * 0.71).cos() * 0.8,
                (b * 0.13).sin() * 1.2,
            ]
        })
        .collect();
    let n = points.len();
    let mut s = Shot::new(
        k,
        CameraPath {
            frames,
            intrinsics: None,
        },
    );
    // Tracks: each point observed (its projection, rounded to 1/64 px like a tracker's output)
    // from its first frame inside the image until it leaves it.
    let mut tracks = Vec::new();
    for (j, p) in points.iter().enumerate() {
        let p = Point3::new(p[0], p[1], p[2]);
        let mut run: Vec<[f64; 2]> = Vec::new();
        let mut first = None;
        for (fi, f) in s.path.frames.iter().enumerate() {
            let cam = Camera {
                intrinsics: s.intrinsics_at(fi),
                pose: f.pose.clone(),
            };
            let inside = cam.depth(&p) > 0.0
                && cam
                    .project(&p)
                    .is_ok_and(|x| x.x >= 0.0 && x.y >= 0.0 && x.x <= 1279.0 && x.y <= 719.0);
            if inside {
                let x = cam.project(&p).unwrap();
                first.get_or_insert(fi);
                run.push([(x.x * 64.0).round() / 64.0, (x.y * 64.0).round() / 64.0]);
            } else if first.is_some() {
                break;
            }
        }
        if let Some(first) = first {
            tracks.push(Track {
                id: j as u64,
                slot: j,
                first,
                points: run,
                lost: None,
            });
        }
    }
    s.tracks = Some(Tracks {
        frames: s.path.frames.iter().map(|f| f.frame as i64).collect(),
        slots: n,
        image_size: None,
        tracks,
    });
    s.cloud = Some(PointCloud {
        points,
        track_ids: (0..n as u64).collect(),
        errors: vec![0.3; n],
        ..Default::default()
    });
    s
}

/// Our reprojections of every point in every frame (the checkers' truth).
fn truth(shot: &Shot, o: &SceneOptions, path: &Path) {
    write_truth(shot, o, path, Through::Lens);
}

/// Which pixels the truth holds.
#[derive(Clone, Copy, PartialEq)]
enum Through {
    /// Through K's lens (the plate's pixels), only those inside the frame when there is a lens.
    Lens,
    /// The pinhole projections (what a render camera sees), plus a grid of our lens's
    /// undistorted pixels of whole distorted pixels (`lens_grid`: d.x d.y u.x u.y).
    PinholeAndGrid,
}

fn write_truth(shot: &Shot, o: &SceneOptions, path: &Path, through: Through) {
    let k = &shot.intrinsics;
    let (w, h) = (k.width.unwrap() as f64, k.height.unwrap() as f64);
    let k_proj = match through {
        Through::Lens => k.clone(),
        Through::PinholeAndGrid => k.pinhole(),
    };
    let frames: Vec<_> = shot
        .path
        .frames
        .iter()
        .map(|f| {
            // A zoom: the frame's own focal length.
            let mut intrinsics = k_proj.clone();
            if let Some(focal) = f.focal {
                intrinsics.f2 *= focal / intrinsics.f1;
                intrinsics.f1 = focal;
            }
            let cam = Camera {
                intrinsics,
                pose: f.pose.clone(),
            };
            let pixels: Vec<_> = shot
                .points()
                .iter()
                .map(|p: &Point3<f64>| match cam.project(p) {
                    Ok(x)
                        if cam.depth(p) > 0.0
                            && (k.is_pinhole()
                                || through == Through::PinholeAndGrid
                                || (x.x >= -0.5
                                    && x.y >= -0.5
                                    && x.x <= w - 0.5
                                    && x.y <= h - 0.5)) =>
                    {
                        json!([x.x, x.y])
                    }
                    _ => serde_json::Value::Null,
                })
                .collect();
            json!({"frame": f.frame, "target_frame": o.target_frame(f.frame), "pixels": pixels})
        })
        .collect();
    let mut doc = json!({
        "width": shot.intrinsics.width,
        "height": shot.intrinsics.height,
        "fps": o.fps,
        "start_frame": o.start_frame,
        "plate": shot.image_pattern.is_some(),
        "frames": frames,
    });
    if !k.is_pinhole() {
        doc["lens"] = serde_json::to_value(k.distortion).unwrap();
    }
    if let Some(st) = &shot.st_map {
        doc["st_map"] = json!(st);
    }
    if through == Through::PinholeAndGrid && !k.is_pinhole() {
        let mut grid = Vec::new();
        for y in (4..h as u32 - 4).step_by(12) {
            for x in (4..w as u32 - 4).step_by(12) {
                let d = nalgebra::Point2::new(x as f64, y as f64);
                let u = k.undistort_pixel(&d).unwrap();
                if u.x >= 2.0 && u.y >= 2.0 && u.x <= w - 3.0 && u.y <= h - 3.0 {
                    grid.push([d.x, d.y, u.x, u.y]);
                }
            }
        }
        doc["lens_grid"] = json!(grid);
    }
    std::fs::write(path, serde_json::to_string(&doc).unwrap()).unwrap();
}

/// Brown–Conrady with the dev plate's coefficients (`blender_plate_dev/distorted`) and a k3.
fn brown() -> Distortion {
    Distortion::BrownConrady {
        k1: -0.16,
        k2: 0.045,
        k3: -0.004,
        p1: 0.0008,
        p2: -0.0005,
    }
}

/// A moderate division lens (Fitzgibbon's model), for the refits.
fn division() -> Distortion {
    Distortion::Division { k1: 0.08, k2: 0.0 }
}

/// A square-pixel K with an off-centre principal point (Blender's tracking camera needs square
/// pixels).
fn square_k() -> Intrinsics {
    Intrinsics::new(920.0, 920.0, 652.25, 341.5).with_size(1280, 720)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vfxgraph-clients-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// An off-centre principal point and non-square pixels (f2 ≠ f1).
fn odd_k() -> Intrinsics {
    Intrinsics::new(1100.0, 1122.0, 652.25, 341.5).with_size(1280, 720)
}

/// The book's K (g7cam.txt) when the shared data is there (under CI=true it must be), else
/// its values.
fn book_k() -> Intrinsics {
    let k = match vfxgraph_testdata::path("book-demo/g7cam.txt") {
        Some(p) => vfxgraph_geometry::formats::read_intrinsics(&p).unwrap(),
        None => Intrinsics::new(1228.4022637363655, 1228.4022637363655, 639.5, 359.5),
    };
    k.with_size(1280, 720)
}

#[test]
fn colmap_export_reads_in_pycolmap_and_round_trips() {
    for (name, k) in [("odd", odd_k()), ("book", book_k())] {
        let dir = tmp(&format!("colmap-{name}"));
        let s = shot(k);
        let o = SceneOptions::default();
        let cams = dir.join("sparse/cameras.txt");
        let files = export("colmap", &cams, &s, &o).unwrap();
        assert_eq!(files.len(), 3);
        // Round trip through the files: import(export) == original within 1e-9.
        let m = colmap::read(&cams).unwrap();
        assert_eq!(m.intrinsics, s.intrinsics);
        for (a, b) in s.path.frames.iter().zip(&m.path.frames) {
            assert_eq!(a.frame, b.frame);
            assert!((a.pose.r - b.pose.r).abs().max() < 1e-9);
            assert!((a.pose.t - b.pose.t).abs().max() < 1e-9);
        }
        assert_eq!(m.cloud.points, s.cloud.as_ref().unwrap().points);
        if python().has("pycolmap") {
            let t = dir.join("truth.json");
            truth(&s, &o, &t);
            // Observations are projections rounded to 1/64 px: at most √2/128 px off.
            check(
                "colmap_check.py",
                &dir.join("sparse"),
                &t,
                &["--obs-tol", "0.01105"],
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// The COLMAP export of shots through a lens: the model that holds it, read back exactly, and
/// pycolmap's projections through its distortion equal ours (1e-6 px for Brown–Conrady; for
/// the division lens, refitted as FULL_OPENCV, within the refit's stated error).
#[test]
fn colmap_export_with_a_lens_reads_in_pycolmap_and_round_trips() {
    let cases = [
        (
            "opencv",
            odd_k().with_distortion(Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 0.0008,
                p2: -0.0005,
            }),
            "OPENCV",
        ),
        ("full", odd_k().with_distortion(brown()), "FULL_OPENCV"),
        (
            "radial",
            square_k().with_distortion(Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 0.0,
                p2: 0.0,
            }),
            "RADIAL",
        ),
        (
            "division",
            square_k().with_distortion(division()),
            "FULL_OPENCV",
        ),
    ];
    for (name, k, model) in cases {
        let dir = tmp(&format!("colmap-lens-{name}"));
        let s = shot(k);
        let o = SceneOptions::default();
        let cams = dir.join("sparse/cameras.txt");
        export("colmap", &cams, &s, &o).unwrap();
        let text = std::fs::read_to_string(&cams).unwrap();
        assert!(text.contains(&format!("\n1 {model} 1280 720 ")), "{text}");
        let cam = colmap::camera_model(&s.intrinsics).unwrap();
        let m = colmap::read(&cams).unwrap();
        if cam.fit_error_px.is_none() {
            assert_eq!(m.intrinsics, s.intrinsics, "{name}");
        }
        for (a, b) in s.path.frames.iter().zip(&m.path.frames) {
            assert!((a.pose.r - b.pose.r).abs().max() < 1e-9);
            assert!((a.pose.t - b.pose.t).abs().max() < 1e-9);
        }
        if python().has("pycolmap") {
            let t = dir.join("truth.json");
            truth(&s, &o, &t);
            // The refit is within its error of our lens; Brown–Conrady is the same formula.
            let tol = cam.fit_error_px.map_or(1e-6, |e| 1.01 * e + 1e-9);
            eprintln!("{name}: {model}, refit error {:?} px", cam.fit_error_px);
            check(
                "colmap_check.py",
                &dir.join("sparse"),
                &t,
                &[
                    "--tol",
                    &tol.to_string(),
                    "--obs-tol",
                    &(0.01105 + tol).to_string(),
                ],
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn blender_script_builds_the_camera_in_bpy() {
    if !python().has("bpy") {
        return;
    }
    let cases = [
        ("odd", odd_k(), SceneOptions::default()),
        (
            "book",
            book_k(),
            SceneOptions {
                fps: 23.976,
                start_frame: 1001,
                scale: 100.0,
                up: UpAxis::PosZ,
            },
        ),
    ];
    for (name, k, o) in cases {
        let dir = tmp(&format!("blender-{name}"));
        let mut s = shot(k);
        s.image_pattern = Some("plate/frame.%04d.png".into());
        // One plate image, so the script's background image sequence is built.
        std::fs::create_dir_all(dir.join("plate")).unwrap();
        let first = s.path.frames[0].frame;
        let img = vfxgraph_imaging::Image::from_fn(8, 8, 3, |_, _, c| 0.2 * c as f32);
        vfxgraph_imaging::io::write_image(&dir.join(format!("plate/frame.{first:04}.png")), &img)
            .unwrap();
        let script = dir.join("camera.py");
        export("blender", &script, &s, &o).unwrap();
        let t = dir.join("truth.json");
        truth(&s, &o, &t);
        check("blender_check.py", &script, &t, &[]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// Blender with a lens: the scene camera is the pinhole K, and Blender's own distortion of the
/// script's tracking camera (the compositor's Movie Distortion node) equals ours within
/// 5e-4 px (Brown–Conrady), plus the refit's error for the division lens.
#[test]
fn blender_tracking_camera_distorts_like_ours() {
    if !python().has("bpy") {
        return;
    }
    for (name, d) in [("brown", brown()), ("division", division())] {
        let dir = tmp(&format!("blender-lens-{name}"));
        let k = square_k().with_distortion(d);
        let mut s = shot(k);
        s.image_pattern = Some("plate/frame.%04d.png".into());
        std::fs::create_dir_all(dir.join("plate")).unwrap();
        let first = s.path.frames[0].frame;
        let img = vfxgraph_imaging::Image::from_fn(8, 8, 3, |_, _, c| 0.2 * c as f32);
        vfxgraph_imaging::io::write_image(&dir.join(format!("plate/frame.{first:04}.png")), &img)
            .unwrap();
        let o = SceneOptions::default();
        let script = dir.join("camera.py");
        export("blender", &script, &s, &o).unwrap();
        let t = dir.join("truth.json");
        write_truth(&s, &o, &t, Through::PinholeAndGrid);
        let fit = vfxgraph_exchange::blender::tracking_camera(&s)
            .unwrap()
            .unwrap()
            .fit_error_px;
        // The ramp is float32: 1.2e-4 px steps at 1024–2048 px; Blender's distortion agrees
        // to 2.5e-4 px (bpy 5.0.1), the refit adds its own error.
        let tol = 5e-4 + fit.unwrap_or(0.0);
        eprintln!("{name}: Blender BROWN, refit error {fit:?} px");
        check(
            "blender_check.py",
            &script,
            &t,
            &["--lens-tol", &tol.to_string()],
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// USD with a lens and an ST-map: the camera prim's `vfxgraph:lens:*` attributes read in
/// usd-core give back our lens, and the frustum's projections taken through it land on our
/// distorted pixels within 0.01 px.
#[test]
fn usd_lens_attributes_reproject_like_ours() {
    if !python().has("pxr.Usd") {
        return;
    }
    for (name, k) in [
        ("brown", odd_k().with_distortion(brown())),
        ("division", square_k().with_distortion(division())),
    ] {
        let dir = tmp(&format!("usd-lens-{name}"));
        let mut s = shot(k);
        s.st_map = Some("lens/st_distort.exr".into());
        let o = SceneOptions::default();
        let stage = dir.join("shot.usda");
        export("usd", &stage, &s, &o).unwrap();
        let t = dir.join("truth.json");
        truth(&s, &o, &t);
        check("usd_check.py", &stage, &t, &[]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn usd_stage_opens_in_usd_core() {
    if !python().has("pxr.Usd") {
        return;
    }
    let cases = [
        ("odd", odd_k(), SceneOptions::default()),
        (
            "book",
            book_k(),
            SceneOptions {
                fps: 25.0,
                start_frame: 0,
                scale: 100.0,
                up: UpAxis::NegZ,
            },
        ),
    ];
    for (name, k, o) in cases {
        let dir = tmp(&format!("usd-{name}"));
        let s = shot(k);
        let stage = dir.join("shot.usda");
        export("usd", &stage, &s, &o).unwrap();
        let t = dir.join("truth.json");
        truth(&s, &o, &t);
        check("usd_check.py", &stage, &t, &[]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// The PLY export loads in a real PLY reader (Blender's importer): every vertex where our point
/// is, every colour exactly ours.
#[test]
fn ply_cloud_imports_in_blender() {
    if !python().has("bpy") {
        return;
    }
    let dir = tmp("ply");
    let mut s = shot(book_k());
    let n = s.cloud.as_ref().unwrap().points.len();
    s.colors = Some(
        (0..n)
            .map(|j| {
                [
                    (j * 37 % 256) as u8,
                    (j * 91 % 256) as u8,
                    (255 - j % 256) as u8,
                ]
            })
            .collect(),
    );
    let ply = dir.join("cloud.ply");
    export("ply", &ply, &s, &SceneOptions::default()).unwrap();
    let t = dir.join("truth.json");
    let doc = json!({"points": s.cloud.as_ref().unwrap().points, "colors": s.colors});
    std::fs::write(&t, serde_json::to_string(&doc).unwrap()).unwrap();
    check("ply_check.py", &ply, &t, &[]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A zoom (a focal length per frame, 900 → 1290 px) in every client that carries one: COLMAP
/// as a camera per image (read back, and pycolmap projecting through each image's camera),
/// Blender as the keyframed lens, USD as `focalLength` time samples — each client's
/// projection of every point in every frame equal to ours.
#[test]
fn a_zoom_exports_to_colmap_blender_and_usd() {
    let s = shot_zooming(square_k(), Some(&|i| 900.0 + 10.0 * i as f64));
    let o = SceneOptions::default();
    let dir = tmp("zoom");
    let t = dir.join("truth.json");
    std::fs::create_dir_all(&dir).unwrap();
    truth(&s, &o, &t);
    let cams = dir.join("sparse/cameras.txt");
    export("colmap", &cams, &s, &o).unwrap();
    let m = colmap::read(&cams).unwrap();
    for (a, b) in s.path.frames.iter().zip(&m.path.frames) {
        assert_eq!(a.focal, b.focal);
    }
    if python().has("pycolmap") {
        check(
            "colmap_check.py",
            &dir.join("sparse"),
            &t,
            &["--obs-tol", "0.01105"],
        );
    }
    if python().has("bpy") {
        let script = dir.join("camera.py");
        export("blender", &script, &s, &o).unwrap();
        check("blender_check.py", &script, &t, &[]);
    }
    if python().has("pxr.Usd") {
        let usda = dir.join("camera.usda");
        export("usd", &usda, &s, &o).unwrap();
        check("usd_check.py", &usda, &t, &[]);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
