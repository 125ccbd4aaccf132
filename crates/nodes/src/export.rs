//! Camera exchange nodes (the solved shot for other programs, book §7.13 and §2.8):
//! `export_cameras` and `import_cameras`. The formats and their conventions live in
//! `vfxgraph_geometry::export`.

use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, OptIn, OptSeqIn, Out, Registry};
use vfxgraph_exchange::files::{report, write_with};
use vfxgraph_exchange::{read, ExportFormat, ExportOptions, ImportFormat};
use vfxgraph_imaging::Image;
use vfxgraph_params::Options;

use crate::artifacts::{images, CameraPathArt, ImageArt, IntrinsicsArt, PointCloudArt, ReportArt};
use crate::tracking::TracksArt;

/// `export_cameras`' format (its other options, after the file: [`ExportOptions`]).
#[derive(Options)]
struct ExportFormatOptions {
    /// colmap, blender, usd, nuke, json or ply
    #[param(required)]
    format: ExportFormat,
}

/// Required: its `Default` only gives the derive a value to start from.
impl Default for ExportFormatOptions {
    fn default() -> Self {
        ExportFormatOptions {
            format: ExportFormat::Colmap,
        }
    }
}

/// `import_cameras`' format.
#[derive(Options)]
struct ImportFormatOptions {
    /// colmap or book
    #[param(required)]
    format: ImportFormat,
}

/// Required: its `Default` only gives the derive a value to start from.
impl Default for ImportFormatOptions {
    fn default() -> Self {
        ImportFormatOptions {
            format: ImportFormat::Colmap,
        }
    }
}

const CAMERAS: In<CameraPathArt> = In::new("cameras", "the solved cameras");
const INTRINSICS: OptIn<IntrinsicsArt> = OptIn::new(
    "intrinsics",
    "K shared by every frame, when the camera path does not carry it (with the image \
     size, or connect the plate or set width/height)",
);
const PLATE: OptSeqIn<ImageArt> = OptSeqIn::new("plate", "the plate: image size and point colours");
const POINTS: OptIn<PointCloudArt> = OptIn::new("points", "the solved points");
const TRACKS: OptIn<TracksArt> = OptIn::new(
    "tracks",
    "the observations: COLMAP 2-D points and tracks (only those the solve kept as \
     inliers linked to a point, per the points' inlier marks), per-frame solve error \
     over the inliers",
);
const REPORT: Out<ReportArt> = Out::new(
    "report",
    "format, files written, frames, points, image size",
);
const BOOK_K: OptIn<IntrinsicsArt> = OptIn::new(
    "intrinsics",
    "K of the book's format (ignored for colmap, which carries its own)",
);
const CAMERAS_OUT: Out<CameraPathArt> = Out::new("cameras", "one [R|t] per frame");
const INTRINSICS_OUT: Out<IntrinsicsArt> = Out::new("intrinsics", "K");
const POINTS_OUT: Out<PointCloudArt> = Out::new(
    "points",
    "COLMAP's points (track id = point id), empty for the book's format",
);

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "export_cameras",
            "Writes a solved shot (camera path + K, optional points, tracks and plate) for another \
             program: `colmap` (text model: `path` is its cameras.txt, images.txt and points3D.txt \
             go beside it), `blender` (a Python script), `usd` (.usda stage), `nuke` (.chan plus a \
             `<name>_filmback.txt` note), `json` (per frame K, R, t, centre, solve error) or `ply` \
             (the points, coloured from the plate). COLMAP, JSON and PLY stay in the solve's world; \
             Blender, USD and Nuke get scale · W · X with W turning `up_axis` into the target's up. \
             A lens on K goes along: COLMAP's SIMPLE_RADIAL/RADIAL/OPENCV/FULL_OPENCV, Blender's \
             movie-clip tracking camera (BROWN), USD `vfxgraph:lens:*` attributes, the Nuke note's \
             Lens section, JSON `distortion` (a division lens is refitted where the target has no \
             such model, with the fit error stated). Writes are atomic.",
        )
        .mode(Mode::Once)
        .input(CAMERAS)
        .input(INTRINSICS)
        .input(POINTS)
        .input(TRACKS)
        .input(PLATE)
        .options::<ExportFormatOptions>()
        .output_file_param("path", "the file to write (colmap: the model's cameras.txt)")
        .options::<ExportOptions>()
        .output(REPORT),
        run_export,
    );
    r.register_fn(
        NodeSpec::new(
            "import_cameras",
            "Reads a solve made elsewhere: a COLMAP text model (`path` is its cameras.txt; one \
             K for every image, with its lens from SIMPLE_RADIAL/RADIAL/OPENCV/FULL_OPENCV; the frame is the last number in each image name) or the \
             book's cameras file (`Frame i`, R, t; K from the `intrinsics` input).",
        )
        .mode(Mode::Once)
        .input(BOOK_K)
        .options::<ImportFormatOptions>()
        .input_file_param("path", "COLMAP cameras.txt (images.txt and points3D.txt beside it) or the book's cameras file")
        .output(CAMERAS_OUT)
        .output(INTRINSICS_OUT)
        .output(POINTS_OUT),
        run_import,
    );
}

fn run_export(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let ExportFormatOptions { format } = ctx.options()?;
    let o: ExportOptions = ctx.options()?;
    let path = &ctx.get(CAMERAS)?.0;
    let k = crate::intrinsics_or_path_k(ctx, INTRINSICS, Some(path))?
        .cloned()
        .ok_or_else(|| {
            NodeError::msg("no K: the camera path carries none, so connect `intrinsics`")
        })?;
    let cloud = ctx.get(POINTS)?.map(|c| c.0.clone());
    let tracks = ctx.get(TRACKS)?.map(|t| t.0.clone());
    let plate: Vec<(i64, &Image)> = ctx.get(PLATE)?.map(images).unwrap_or_default();
    let shot = o.shot(k, path.clone(), cloud, tracks, &plate)?;
    // Through the context: every file is recorded as an output (COLMAP's images.txt and
    // points3D.txt, Nuke's film-back note), so deleting one makes the entry stale.
    let path = ctx.path("path");
    let files = write_with(format, &path, &shot, &o.scene, |p, text| {
        ctx.write_file(p, text.as_bytes())
    })?;
    ctx.set(REPORT, ReportArt(report(format, &shot, &files)));
    Ok(())
}

fn run_import(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let ImportFormatOptions { format } = ctx.options()?;
    let k = ctx.get(BOOK_K)?.map(|k| &k.0);
    let (cameras, intrinsics, cloud) = read(format, &ctx.path("path"), k)?;
    ctx.set(CAMERAS_OUT, CameraPathArt(cameras));
    ctx.set(INTRINSICS_OUT, IntrinsicsArt(intrinsics));
    ctx.set(POINTS_OUT, PointCloudArt(cloud));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::Vector3;
    use std::path::Path;
    use vfxgraph_engine::ParamValue;
    use vfxgraph_engine::{InputValue, Value};
    use vfxgraph_geometry::camera::Pose;
    use vfxgraph_geometry::formats;
    use vfxgraph_geometry::formats::{CameraPath, FramePose};
    use vfxgraph_geometry::points::PointCloud;
    use vfxgraph_geometry::rotation::axis_angle_to_r;
    use vfxgraph_geometry::Intrinsics;

    fn path() -> CameraPath {
        CameraPath {
            frames: (0..6)
                .map(|i| {
                    let a = i as f64;
                    FramePose {
                        frame: 3 + i,
                        pose: Pose::new(
                            axis_angle_to_r(&Vector3::new(0.01 * a, 0.1 - 0.03 * a, 0.2)),
                            Vector3::new(0.1 * a, -0.2, 4.0 + 0.01 * a),
                        ),
                        focal: None,
                    }
                })
                .collect(),
            intrinsics: None,
        }
    }

    fn cloud() -> PointCloud {
        PointCloud {
            points: (0..20)
                .map(|j| {
                    let b = j as f64;
                    [
                        (b * 0.3).sin(),
                        (b * 0.7).cos() * 0.5,
                        (b * 1.1).sin() * 0.4,
                    ]
                })
                .collect(),
            track_ids: (0..20).collect(),
            errors: vec![0.25; 20],
            ..Default::default()
        }
    }

    fn run(
        name: &str,
        set: &[(&str, ParamValue)],
        inputs: Vec<(&'static str, InputValue<'static>)>,
        dir: &Path,
    ) -> Result<Context<'static>, NodeError> {
        let s: &'static _ = Box::leak(Box::new(spec(name)));
        let p: &'static _ = Box::leak(Box::new(params(s, set)));
        let d: &'static Path = Box::leak(dir.to_path_buf().into_boxed_path());
        let mut ctx = Context::for_test(s, p, d, None, inputs);
        crate::registry().node(name).unwrap().run(&mut ctx)?;
        Ok(ctx)
    }

    /// Export to COLMAP through the node, import through the node: the same K with its lens
    /// (exactly), path and points within 1e-9; every other format writes its files and reports
    /// them and the lens.
    #[test]
    fn export_then_import_round_trips_and_all_formats_write() {
        let dir = std::env::temp_dir().join(format!("vfxgraph-export-node-{}", std::process::id()));
        let k = Intrinsics::new(1228.4, 1228.4, 639.5, 359.5)
            .with_size(1280, 720)
            .with_distortion(vfxgraph_geometry::lens::Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 0.0008,
                p2: -0.0005,
            });
        let inputs = || {
            vec![
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path()))),
                ),
                (
                    "intrinsics",
                    InputValue::One(Value::new(IntrinsicsArt(k.clone()))),
                ),
                (
                    "points",
                    InputValue::One(Value::new(PointCloudArt(cloud()))),
                ),
            ]
        };
        for (fmt, file, n) in [
            ("colmap", "colmap/cameras.txt", 3),
            ("blender", "cam.py", 1),
            ("usd", "cam.usda", 1),
            ("nuke", "cam.chan", 2),
            ("json", "cam.json", 1),
            ("ply", "points.ply", 1),
        ] {
            let mut ctx = run(
                "export_cameras",
                &[
                    ("format", ParamValue::Str(fmt.into())),
                    ("path", ParamValue::Str(file.into())),
                ],
                inputs(),
                &dir,
            )
            .unwrap();
            let rep = ctx.take_output::<ReportArt>("report").unwrap().0;
            let files = rep["files"].as_array().unwrap();
            assert_eq!(files.len(), n, "{fmt}: {rep}");
            assert_eq!(rep["lens"], "brown_conrady");
            for f in files {
                assert!(Path::new(f.as_str().unwrap()).is_file(), "{f}");
            }
        }
        assert!(dir.join("cam_filmback.txt").is_file());
        let mut ctx = run(
            "import_cameras",
            &[
                ("format", ParamValue::Str("colmap".into())),
                ("path", ParamValue::Str("colmap/cameras.txt".into())),
            ],
            vec![],
            &dir,
        )
        .unwrap();
        let back = ctx.take_output::<CameraPathArt>("cameras").unwrap().0;
        let kb = ctx.take_output::<IntrinsicsArt>("intrinsics").unwrap().0;
        let pts = ctx.take_output::<PointCloudArt>("points").unwrap().0;
        assert_eq!(kb, k);
        let orig = path();
        assert_eq!(back.frames.len(), orig.frames.len());
        for (a, b) in orig.frames.iter().zip(&back.frames) {
            assert_eq!(a.frame, b.frame);
            assert!((a.pose.r - b.pose.r).abs().max() < 1e-9);
            assert!((a.pose.t - b.pose.t).abs().max() < 1e-9);
        }
        assert_eq!(pts.points, cloud().points);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A plate sequence gives the image size (K has none) and the points' colours; the book's
    /// cameras format imports with the K given on the input.
    #[test]
    fn plate_colours_points_and_book_format_imports() {
        let dir =
            std::env::temp_dir().join(format!("vfxgraph-export-plate-{}", std::process::id()));
        let k = Intrinsics::new(500.0, 500.0, 319.5, 239.5);
        let plate: Vec<(i64, Value)> = path()
            .frames
            .iter()
            .map(|f| {
                let img = Image::from_fn(640, 480, 3, |_, _, c| [0.5, 0.25, 0.0][c]);
                (f.frame as i64, Value::new(ImageArt(img)))
            })
            .collect();
        let mut ctx = run(
            "export_cameras",
            &[
                ("format", ParamValue::Str("ply".into())),
                ("path", ParamValue::Str("p.ply".into())),
            ],
            vec![
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path()))),
                ),
                (
                    "intrinsics",
                    InputValue::One(Value::new(IntrinsicsArt(k.clone()))),
                ),
                (
                    "points",
                    InputValue::One(Value::new(PointCloudArt(cloud()))),
                ),
                ("plate", InputValue::Sequence(plate)),
            ],
            &dir,
        )
        .unwrap();
        let rep = ctx.take_output::<ReportArt>("report").unwrap().0;
        assert_eq!(
            (rep["width"].as_u64(), rep["height"].as_u64()),
            (Some(640), Some(480))
        );
        assert_eq!(rep["coloured"], true);
        let text = std::fs::read_to_string(dir.join("p.ply")).unwrap();
        let want = format!(
            " {} {} 0 ",
            vfxgraph_imaging::color::linear_to_srgb8(0.5),
            vfxgraph_imaging::color::linear_to_srgb8(0.25)
        );
        let body = text.split("end_header\n").nth(1).unwrap();
        assert_eq!(body.lines().count(), 20);
        assert!(body.lines().all(|l| l.contains(&want)), "{body}");

        formats::write_cameras(&dir.join("book.txt"), &path()).unwrap();
        let mut ctx = run(
            "import_cameras",
            &[
                ("format", ParamValue::Str("book".into())),
                ("path", ParamValue::Str("book.txt".into())),
            ],
            vec![(
                "intrinsics",
                InputValue::One(Value::new(IntrinsicsArt(k.clone()))),
            )],
            &dir,
        )
        .unwrap();
        let back = ctx.take_output::<CameraPathArt>("cameras").unwrap().0;
        assert_eq!(back.frames, path().frames);
        assert_eq!(back.intrinsics.as_ref(), Some(&k));
        assert_eq!(ctx.take_output::<IntrinsicsArt>("intrinsics").unwrap().0, k);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_input_gives_clear_errors() {
        let dir = std::env::temp_dir().join(format!("vfxgraph-export-bad-{}", std::process::id()));
        let no_size = Intrinsics::new(1000.0, 1000.0, 320.0, 240.0);
        let e = run(
            "export_cameras",
            &[
                ("format", ParamValue::Str("usd".into())),
                ("path", ParamValue::Str("a.usda".into())),
            ],
            vec![
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path()))),
                ),
                (
                    "intrinsics",
                    InputValue::One(Value::new(IntrinsicsArt(no_size))),
                ),
            ],
            &dir,
        )
        .err()
        .unwrap();
        assert!(e.to_string().contains("image size"), "{e}");
        let e = run(
            "export_cameras",
            &[
                ("format", ParamValue::Str("json".into())),
                ("path", ParamValue::Str("a.json".into())),
            ],
            vec![(
                "cameras",
                InputValue::One(Value::new(CameraPathArt(path()))),
            )],
            &dir,
        )
        .err()
        .unwrap();
        assert!(e.to_string().contains("no K"), "{e}");
        let k = Intrinsics::new(1000.0, 1000.0, 320.0, 240.0).with_size(640, 480);
        let e = run(
            "export_cameras",
            &[
                ("format", ParamValue::Str("colmap".into())),
                ("path", ParamValue::Str("model.txt".into())),
            ],
            vec![
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path()))),
                ),
                (
                    "intrinsics",
                    InputValue::One(Value::new(IntrinsicsArt(k.clone()))),
                ),
            ],
            &dir,
        )
        .err()
        .unwrap();
        assert!(e.to_string().contains("cameras.txt"), "{e}");
        let e = run(
            "export_cameras",
            &[
                ("format", ParamValue::Str("ply".into())),
                ("path", ParamValue::Str("p.ply".into())),
            ],
            vec![
                (
                    "cameras",
                    InputValue::One(Value::new(CameraPathArt(path()))),
                ),
                ("intrinsics", InputValue::One(Value::new(IntrinsicsArt(k)))),
            ],
            &dir,
        )
        .err()
        .unwrap();
        assert!(e.to_string().contains("points"), "{e}");
        let e = run(
            "import_cameras",
            &[
                ("format", ParamValue::Str("book".into())),
                ("path", ParamValue::Str("nothing.txt".into())),
            ],
            vec![],
            &dir,
        )
        .err()
        .unwrap();
        assert!(e.to_string().contains("intrinsics"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
