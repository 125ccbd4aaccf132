//! Camera calibration nodes (book chapters 2–5): `read_intrinsics`, `read_points2d`,
//! `read_points3d`, `calibrate_camera`, `two_view`, `write_camera`, `write_report`, and
//! `intrinsics_from_metadata` (K from a photograph's EXIF focal length).

use vfxgraph_engine::{ArtifactType, Context, In, Mode, NodeError, NodeSpec, Out, Registry};
use vfxgraph_geometry::calibration::{calibrate_camera, CalibrateCameraOptions};
use vfxgraph_geometry::formats;
use vfxgraph_geometry::two_view::{reconstruct_two_view, TwoViewRansacOptions};

use crate::artifacts::{CameraArt, IndicesArt, IntrinsicsArt, Points2dArt, Points3dArt, ReportArt};

/// Reads file param `path` with `read` and sets output `port` to `wrap` of what it read.
fn read_into<T, A: ArtifactType, E: std::error::Error>(
    ctx: &mut Context<'_>,
    port: Out<A>,
    read: fn(&std::path::Path) -> Result<T, E>,
    wrap: fn(T) -> A,
) -> Result<(), NodeError> {
    let value = read(&ctx.path("path"))?;
    ctx.set(port, wrap(value));
    Ok(())
}

/// A node run once that reads file `path` (documented by `path_doc`) into output `port`.
fn file_reader<A: ArtifactType>(
    name: &'static str,
    doc: &'static str,
    path_doc: &'static str,
    port: Out<A>,
) -> NodeSpec {
    NodeSpec::new(name, doc)
        .mode(Mode::Once)
        .input_file_param("path", path_doc)
        .output(port)
}

/// K of a photograph or plate frame from its EXIF focal length
/// ([`vfxgraph_imaging::metadata::camera_focal`]), square pixels, the principal point at the
/// image's centre, its size set.
fn run_intrinsics_from_metadata(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let path = ctx.path("path");
    if is_movie(&path) {
        return intrinsics_from_movie(ctx, &path);
    }
    let img = vfxgraph_imaging::io::read_image(&path)?;
    let bytes = std::fs::read(&path)
        .map_err(|e| NodeError::msg(format!("cannot read {}: {e}", path.display())))?;
    let f = vfxgraph_imaging::metadata::camera_focal(&bytes, img.width, img.height)
        .map_err(|e| NodeError::msg(format!("{}: {e}", path.display())))?;
    let (w, h) = (img.width as f64, img.height as f64);
    let k =
        vfxgraph_geometry::Intrinsics::new(f.pixels, f.pixels, (w - 1.0) / 2.0, (h - 1.0) / 2.0)
            .with_size(img.width as u32, img.height as u32);
    ctx.set(METADATA_K, IntrinsicsArt(k));
    Ok(())
}

/// A QuickTime / MP4 file, by its extension.
fn is_movie(path: &std::path::Path) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("mov" | "mp4" | "m4v" | "3gp"))
}

/// K of a clip from the 35 mm equivalent focal length a phone records in its QuickTime
/// metadata ([`vfxgraph_video::metadata`]), for the picture as shown (portrait clips turned).
fn intrinsics_from_movie(ctx: &mut Context<'_>, path: &std::path::Path) -> Result<(), NodeError> {
    let m = vfxgraph_video::metadata::camera_metadata(path).map_err(NodeError::msg)?;
    let (w, h) = m
        .display_size
        .ok_or_else(|| NodeError::msg(format!("{}: no video track with a size", path.display())))?;
    let f35 = m.focal_35mm.ok_or_else(|| {
        NodeError::msg(format!(
            "{}: the QuickTime metadata has no {} (the camera did not record its focal              length: use `matchmove` with `focal: unknown`)",
            path.display(),
            vfxgraph_video::metadata::KEY_FOCAL_35MM
        ))
    })?;
    let f = vfxgraph_imaging::metadata::pixels_from_35mm(f35, w as usize, h as usize);
    let (wf, hf) = (w as f64, h as f64);
    let k = vfxgraph_geometry::Intrinsics::new(f, f, (wf - 1.0) / 2.0, (hf - 1.0) / 2.0)
        .with_size(w, h);
    ctx.set(METADATA_K, IntrinsicsArt(k));
    Ok(())
}

const METADATA_K: Out<IntrinsicsArt> = Out::new("intrinsics", "K from the metadata");
const READ_K: Out<IntrinsicsArt> = Out::new("intrinsics", "K");
const READ_POINTS2D: Out<Points2dArt> = Out::new("points", "pixel coordinates");
const READ_POINTS3D: Out<Points3dArt> = Out::new("points", "world coordinates");
const POINTS3D: In<Points3dArt> = In::new("points3d", "world points");
const POINTS2D: In<Points2dArt> = In::new("points2d", "their projections, same order");
const CAMERA_OUT: Out<CameraArt> = Out::new("camera", "K[R|t]");
const CALIBRATION_REPORT: Out<ReportArt> =
    Out::new("report", "per-point reprojection errors, inliers and RMS");
const POINTS_A: In<Points2dArt> = In::new("points_a", "points in view a");
const POINTS_B: In<Points2dArt> = In::new("points_b", "the same points in view b");
const VIEWS_K: In<IntrinsicsArt> = In::new("intrinsics", "K of both views");
const CAMERA_B: Out<CameraArt> = Out::new("camera_b", "K[R|t] of view b");
const POINTS3D_OUT: Out<Points3dArt> = Out::new("points3d", "triangulated inliers");
const INLIERS: Out<IndicesArt> = Out::new("inliers", "input index of each 3D point");
const TWO_VIEW_REPORT: Out<ReportArt> = Out::new("report", "figures");
const CAMERA: In<CameraArt> = In::new("camera", "the camera");
const INTRINSICS: In<IntrinsicsArt> = In::new("intrinsics", "K");
const REPORT: In<ReportArt> = In::new("report", "the report");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        file_reader(
            "intrinsics_from_metadata",
            "K from the focal length a camera recorded in an image's EXIF (the focal plane's \
             resolution, else the 35 mm equivalent) or in a clip's QuickTime metadata (the 35 \
             mm equivalent phones record, for the picture as shown): a start for `matchmove` \
             (`focal: refine`) on footage shot without a calibration; square pixels, principal \
             point at the centre, the picture's size.",
            "a photograph or frame of the shot with EXIF (JPEG, TIFF, PNG), or the clip itself \
             (MOV, MP4)",
            METADATA_K,
        )
        .threads(vfxgraph_engine::Threads::One)
        .memory(vfxgraph_engine::Memory::Fixed(512)),
        run_intrinsics_from_metadata,
    );
    r.register_fn(
        file_reader(
            "read_intrinsics",
            "Reads camera intrinsics K: the book's g7cam.txt (3×3 matrix, rows) or JSON.",
            "g7cam.txt-style K file, or .json",
            READ_K,
        )
        .threads(vfxgraph_engine::Threads::One)
        .memory(vfxgraph_engine::Memory::Fixed(256)),
        |ctx| read_into(ctx, READ_K, formats::read_intrinsics, IntrinsicsArt),
    );
    r.register_fn(
        file_reader(
            "read_points2d",
            "Reads image points, `u v` per line (the book's calib_projs.txt), or JSON.",
            "points file",
            READ_POINTS2D,
        ),
        |ctx| read_into(ctx, READ_POINTS2D, formats::read_points2d, Points2dArt),
    );
    r.register_fn(
        file_reader(
            "read_points3d",
            "Reads 3D points, `X Y Z` per line, or JSON.",
            "points file",
            READ_POINTS3D,
        ),
        |ctx| read_into(ctx, READ_POINTS3D, formats::read_points3d, Points3dArt),
    );
    r.register_fn(
        NodeSpec::new(
            "calibrate_camera",
            "Calibrates one camera from 3D↔2D matches (book ch. 4): `dlt` (normalized DLT and \
             K[R|t] factoring, §4.1–4.3), `restricted` (DLT start, LM with zero skew, §4.5–4.6) \
             or `tsai` (planar target, known principal point, §4.8), optionally inside RANSAC \
             (§4.7, the book's ransac_singlecam).",
        )
        .input(POINTS3D)
        .input(POINTS2D)
        .options::<CalibrateCameraOptions>()
        .output(CAMERA_OUT)
        .output(CALIBRATION_REPORT),
        run_calibrate,
    );
    r.register_fn(
        NodeSpec::new(
            "two_view",
            "Relative pose and structure from two views with known K (book ch. 5): RANSAC on the \
             normalized 8-point F (Sampson distance in pixels, or the book's algebraic error), \
             E = KᵀFK, the four (R, t) and cheirality, triangulation. Camera a is K[I|0]; |t| = 1.",
        )
        .input(POINTS_A)
        .input(POINTS_B)
        .input(VIEWS_K)
        .options::<TwoViewRansacOptions>()
        .output(CAMERA_B)
        .output(POINTS3D_OUT)
        .output(INLIERS)
        .output(TWO_VIEW_REPORT),
        run_two_view,
    );
    r.register_fn(
        NodeSpec::new(
            "write_camera",
            "Writes a camera as JSON {\"K\": [[3×3]], \"R\": [[3×3]], \"t\": [3], \"width\"?, \
             \"height\"?}, rows first, mapping X to K(RX + t).",
        )
        .input(CAMERA)
        .output_file_param("path", "JSON file"),
        |ctx| {
            let cam = &ctx.get(CAMERA)?.0;
            Ok(formats::write_json(&ctx.path("path"), cam)?)
        },
    );
    r.register_fn(
        NodeSpec::new(
            "write_intrinsics",
            "Writes camera intrinsics K as the book's g7cam.txt (3×3, rows), or JSON (with \
             the image size) when the name ends in .json; what `read_intrinsics` reads.",
        )
        .input(INTRINSICS)
        .output_file_param("path", "g7cam.txt-style K file, or .json"),
        |ctx| {
            let k = &ctx.get(INTRINSICS)?.0;
            Ok(formats::write_intrinsics(&ctx.path("path"), k)?)
        },
    );
    r.register_fn(
        NodeSpec::new("write_report", "Writes any report as pretty JSON.")
            .threads(vfxgraph_engine::Threads::One)
            .input(REPORT)
            .output_file_param("path", "JSON file"),
        |ctx| {
            let rep = &ctx.get(REPORT)?.0;
            Ok(formats::write_json(&ctx.path("path"), rep)?)
        },
    );
}

fn run_calibrate(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: CalibrateCameraOptions = ctx.options()?;
    let p3 = &ctx.get(POINTS3D)?.0;
    let p2 = &ctx.get(POINTS2D)?.0;
    let (camera, report) = calibrate_camera(&p3.0, &p2.0, &o.options()?, &mut o.rng())?;
    ctx.set(CAMERA_OUT, CameraArt(camera));
    ctx.set(
        CALIBRATION_REPORT,
        ReportArt(serde_json::to_value(&report)?),
    );
    Ok(())
}

fn run_two_view(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: TwoViewRansacOptions = ctx.options()?;
    let a = &ctx.get(POINTS_A)?.0;
    let b = &ctx.get(POINTS_B)?.0;
    let k = &ctx.get(VIEWS_K)?.0;
    let rec = reconstruct_two_view(&a.0, &b.0, k, k, &o.options(), &mut o.rng())?;
    ctx.set(CAMERA_B, CameraArt(rec.camera_b.clone()));
    ctx.set(POINTS3D_OUT, Points3dArt(rec.points3d.clone()));
    ctx.set(INLIERS, IndicesArt(rec.point_indices.clone()));
    ctx.set(
        TWO_VIEW_REPORT,
        ReportArt(serde_json::to_value(&rec.report)?),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use rand::SeedableRng;
    use rand_pcg::Pcg64;
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_geometry::{synthetic, Camera, Points2d, Points3d};

    struct Scene {
        camera: Camera,
        points3d: Points3d,
        points2d: Points2d,
    }

    fn scene(n: usize, sigma: f64, seed: u64) -> Scene {
        let mut rng = Pcg64::seed_from_u64(seed);
        let camera = synthetic::random_camera(&mut rng);
        let pts = synthetic::random_points_in_frustum(&camera, n, 2.0, 10.0, &mut rng);
        let (obs, _) = synthetic::observe(&camera, &pts, sigma, 0.0, &mut rng);
        Scene {
            camera,
            points3d: Points3d(pts),
            points2d: Points2d(obs),
        }
    }

    /// K from a JPEG whose EXIF gives a phone's 35 mm equivalent (26 mm on 40 × 30 px: the
    /// 36 × 24 mm frame's diagonal field of view): f = 26 · 50 / 43.267 px, centred.
    #[test]
    fn intrinsics_from_metadata_reads_the_exif_focal_length() {
        use exif::experimental::Writer;
        use exif::{Field, In, Tag};
        let mut w = Writer::new();
        let f35 = Field {
            tag: Tag::FocalLengthIn35mmFilm,
            ifd_num: In::PRIMARY,
            value: exif::Value::Short(vec![26]),
        };
        w.push_field(&f35);
        let mut tiff = std::io::Cursor::new(Vec::new());
        w.write(&mut tiff, false).unwrap();
        let mut app1 = b"Exif\0\0".to_vec();
        app1.extend(tiff.into_inner());
        let jpeg = vfxgraph_imaging::io::encode(
            &vfxgraph_imaging::Image::new(40, 30, 3),
            vfxgraph_imaging::Format::Jpeg,
        )
        .unwrap();
        // SOI, then the APP1 segment, then the rest of the JPEG.
        let mut bytes = jpeg[..2].to_vec();
        bytes.extend([0xFF, 0xE1]);
        bytes.extend(((app1.len() + 2) as u16).to_be_bytes());
        bytes.extend(app1);
        bytes.extend(&jpeg[2..]);
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("frame.jpg"), bytes).unwrap();
        let s = spec("intrinsics_from_metadata");
        let p = params(&s, &[("path", ParamValue::Str("frame.jpg".into()))]);
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        run_intrinsics_from_metadata(&mut ctx).unwrap();
        let k = ctx.take_output::<IntrinsicsArt>("intrinsics").unwrap().0;
        let want = 26.0 * 50.0 / 36f64.hypot(24.0);
        assert!(
            (k.f1 - want).abs() < 1e-9 && (k.f2 - want).abs() < 1e-9,
            "{k:?}"
        );
        assert_eq!((k.u0, k.v0), (19.5, 14.5));
        assert_eq!((k.width, k.height), (Some(40), Some(30)));
        // Without EXIF: an error naming the file.
        std::fs::write(
            dir.path().join("bare.jpg"),
            vfxgraph_imaging::io::encode(
                &vfxgraph_imaging::Image::new(4, 4, 3),
                vfxgraph_imaging::Format::Jpeg,
            )
            .unwrap(),
        )
        .unwrap();
        let p = params(&s, &[("path", ParamValue::Str("bare.jpg".into()))]);
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        let e = run_intrinsics_from_metadata(&mut ctx)
            .unwrap_err()
            .to_string();
        assert!(e.contains("bare.jpg") && e.contains("no EXIF"), "{e}");
    }

    /// K of a portrait phone clip from its QuickTime metadata (26 mm equivalent, made by
    /// FFmpeg as phones write it): the picture as shown, 64 × 96, f = 26 · √(64² + 96²) / 43.27.
    #[test]
    fn intrinsics_from_metadata_reads_a_clips_quicktime_focal_length() {
        if !vfxgraph_testdata::tool(vfxgraph_video::ffmpeg::available(), "FFmpeg") {
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let ffmpeg = |args: &[&str]| {
            let ok = std::process::Command::new("ffmpeg")
                .current_dir(dir.path())
                .args(["-v", "error", "-y"])
                .args(args)
                .status()
                .unwrap();
            assert!(ok.success(), "ffmpeg {args:?}");
        };
        ffmpeg(&[
            "-f",
            "lavfi",
            "-i",
            "testsrc=size=96x64:rate=24",
            "-frames:v",
            "2",
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "bare.mp4",
        ]);
        // The display matrix is written on a stream copy (an encode drops the tag).
        let focal = format!("{}=26", vfxgraph_video::metadata::KEY_FOCAL_35MM);
        ffmpeg(&[
            "-i",
            "bare.mp4",
            "-c",
            "copy",
            "-movflags",
            "use_metadata_tags",
            "-metadata",
            &focal,
            "-metadata:s:v:0",
            "rotate=90",
            "clip.mov",
        ]);
        let s = spec("intrinsics_from_metadata");
        let p = params(&s, &[("path", ParamValue::Str("clip.mov".into()))]);
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        run_intrinsics_from_metadata(&mut ctx).unwrap();
        let k = ctx.take_output::<IntrinsicsArt>("intrinsics").unwrap().0;
        let want = 26.0 * 64f64.hypot(96.0) / 36f64.hypot(24.0);
        assert!(
            (k.f1 - want).abs() < 1e-9 && (k.f2 - want).abs() < 1e-9,
            "{k:?}"
        );
        assert_eq!((k.u0, k.v0), (31.5, 47.5));
        assert_eq!((k.width, k.height), (Some(64), Some(96)));
        // A clip without the focal length: an error naming the file and what to do.
        let p = params(&s, &[("path", ParamValue::Str("bare.mp4".into()))]);
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        let e = run_intrinsics_from_metadata(&mut ctx)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bare.mp4") && e.contains("focal: unknown"),
            "{e}"
        );
    }

    #[test]
    fn calibrate_recovers_a_synthetic_camera_through_the_node() {
        let scene = scene(300, 0.5, 7);
        let s = spec("calibrate_camera");
        let p = params(&s, &[("ransac_threshold_px", ParamValue::Float(2.0))]);
        let dir = std::path::Path::new(".");
        let mut ctx = Context::for_test(
            &s,
            &p,
            dir,
            None,
            vec![
                (
                    "points3d",
                    InputValue::One(Value::new(Points3dArt(scene.points3d.clone()))),
                ),
                (
                    "points2d",
                    InputValue::One(Value::new(Points2dArt(scene.points2d.clone()))),
                ),
            ],
        );
        run_calibrate(&mut ctx).unwrap();
        let cam = ctx.take_output::<CameraArt>("camera").unwrap().0;
        let f_err =
            (cam.intrinsics.f1 - scene.camera.intrinsics.f1).abs() / scene.camera.intrinsics.f1;
        assert!(f_err < 0.005, "focal error {f_err}");
        let rep: vfxgraph_geometry::calibration::CalibrationReport = ctx
            .take_output::<ReportArt>("report")
            .unwrap()
            .parse()
            .unwrap();
        assert!(rep.rms < 1.0, "{rep:?}");
        // Tsai without a principal point is a clear error.
        let p = params(&s, &[("method", ParamValue::Str("tsai".into()))]);
        let mut ctx = Context::for_test(
            &s,
            &p,
            dir,
            None,
            vec![
                (
                    "points3d",
                    InputValue::One(Value::new(Points3dArt(scene.points3d))),
                ),
                (
                    "points2d",
                    InputValue::One(Value::new(Points2dArt(scene.points2d))),
                ),
            ],
        );
        assert!(run_calibrate(&mut ctx)
            .unwrap_err()
            .message
            .contains("principal_point"));
    }

    #[test]
    fn too_few_points_is_an_error_not_a_panic() {
        let s = spec("calibrate_camera");
        let p = params(&s, &[]);
        let pts3 = vfxgraph_geometry::Points3d(vec![nalgebra::Point3::new(0.0, 0.0, 1.0); 3]);
        let pts2 = vfxgraph_geometry::Points2d(vec![nalgebra::Point2::new(0.0, 0.0); 3]);
        let mut ctx = Context::for_test(
            &s,
            &p,
            std::path::Path::new("."),
            None,
            vec![
                ("points3d", InputValue::One(Value::new(Points3dArt(pts3)))),
                ("points2d", InputValue::One(Value::new(Points2dArt(pts2)))),
            ],
        );
        let e = run_calibrate(&mut ctx).unwrap_err();
        assert!(!e.message.is_empty());
    }

    #[test]
    fn camera_json_has_the_documented_layout() {
        let dir = tempfile::tempdir().unwrap();
        let scene = scene(20, 0.0, 1);
        let s = spec("write_camera");
        let p = params(&s, &[("path", ParamValue::Str("cams/c.json".into()))]);
        let mut ctx = Context::for_test(
            &s,
            &p,
            dir.path(),
            None,
            vec![(
                "camera",
                InputValue::One(Value::new(CameraArt(scene.camera.clone()))),
            )],
        );
        crate::registry()
            .node("write_camera")
            .unwrap()
            .run(&mut ctx)
            .unwrap();
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("cams/c.json")).unwrap())
                .unwrap();
        let k = &v["K"];
        assert_eq!(k.as_array().unwrap().len(), 3);
        assert!((k[0][0].as_f64().unwrap() - scene.camera.intrinsics.f1).abs() < 1e-9);
        assert!((k[0][2].as_f64().unwrap() - scene.camera.intrinsics.u0).abs() < 1e-9);
        assert_eq!(v["t"].as_array().unwrap().len(), 3);
        assert!((v["R"][1][2].as_f64().unwrap() - scene.camera.pose.r[(1, 2)]).abs() < 1e-12);
        let _ = &mut ctx;
    }
}
