//! Camera calibration nodes (book chapters 2–5): `read_intrinsics`, `read_points2d`,
//! `read_points3d`, `calibrate_camera`, `two_view`, `write_camera`, `write_report`.

use rand::SeedableRng;
use rand_pcg::Pcg64;
use vfxgraph_engine::fsutil::atomic_write;
use vfxgraph_engine::{
    ArtifactType, Context, Mode, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, PathRole,
    PortSpec, Registry,
};
use vfxgraph_vision::calibration::{calibrate_camera, CalibrationMethod, CalibrationOptions};
use vfxgraph_vision::formats;
use vfxgraph_vision::ransac::RansacParams;
use vfxgraph_vision::two_view::{reconstruct_two_view, EpipolarResidual, TwoViewOptions};

use crate::artifacts::{CameraArt, IndicesArt, IntrinsicsArt, Points2dArt, Points3dArt, ReportArt};
use crate::FnNode;

fn path_in(doc: &'static str) -> ParamSpec {
    ParamSpec::required("path", ParamType::Path(PathRole::Input), doc)
}

fn path_out(doc: &'static str) -> ParamSpec {
    ParamSpec::required("path", ParamType::Path(PathRole::Output), doc)
}

fn seed_param() -> ParamSpec {
    ParamSpec::optional(
        "seed",
        ParamType::Int {
            min: 0,
            max: i64::MAX,
        },
        ParamValue::Int(0),
        "RANSAC random seed",
    )
}

fn threshold_param(default: f64, doc: &'static str) -> ParamSpec {
    ParamSpec::optional(
        "ransac_threshold_px",
        ParamType::Float { min: 0.0, max: 1e6 },
        ParamValue::Float(default),
        doc,
    )
}

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_node(FnNode::new(
        NodeSpec::new(
            "read_intrinsics",
            "Reads camera intrinsics K: the book's g7cam.txt (3×3 matrix, rows) or JSON.",
        )
        .mode(Mode::Once)
        .threads(vfxgraph_engine::Threads::One)
        .memory(vfxgraph_engine::Memory::Fixed(256))
        .param(path_in("g7cam.txt-style K file, or .json"))
        .output(PortSpec::one("intrinsics", IntrinsicsArt::NAME, "K")),
        |ctx| {
            let k = formats::read_intrinsics(&ctx.path("path"))?;
            ctx.output("intrinsics", IntrinsicsArt(k));
            Ok(())
        },
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "read_points2d",
            "Reads image points, `u v` per line (the book's calib_projs.txt), or JSON.",
        )
        .mode(Mode::Once)
        .param(path_in("points file"))
        .output(PortSpec::one(
            "points",
            Points2dArt::NAME,
            "pixel coordinates",
        )),
        |ctx| {
            let p = formats::read_points2d(&ctx.path("path"))?;
            ctx.output("points", Points2dArt(p));
            Ok(())
        },
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "read_points3d",
            "Reads 3D points, `X Y Z` per line, or JSON.",
        )
        .mode(Mode::Once)
        .param(path_in("points file"))
        .output(PortSpec::one(
            "points",
            Points3dArt::NAME,
            "world coordinates",
        )),
        |ctx| {
            let p = formats::read_points3d(&ctx.path("path"))?;
            ctx.output("points", Points3dArt(p));
            Ok(())
        },
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "calibrate_camera",
            "Calibrates one camera from 3D↔2D matches (book ch. 4): `dlt` (normalized DLT and \
             K[R|t] factoring, §4.1–4.3), `restricted` (DLT start, LM with zero skew, §4.5–4.6) \
             or `tsai` (planar target, known principal point, §4.8), optionally inside RANSAC \
             (§4.7, the book's ransac_singlecam).",
        )
        .input(PortSpec::one("points3d", Points3dArt::NAME, "world points"))
        .input(PortSpec::one(
            "points2d",
            Points2dArt::NAME,
            "their projections, same order",
        ))
        .param(ParamSpec::optional(
            "method",
            ParamType::Enum(&["dlt", "restricted", "tsai"]),
            ParamValue::Str("restricted".into()),
            "calibration model",
        ))
        .param(ParamSpec::optional(
            "principal_point",
            ParamType::FloatList { len: None },
            ParamValue::List(vec![]),
            "[u0, v0] for tsai (pixels)",
        ))
        .param(threshold_param(
            0.0,
            "RANSAC inlier threshold in pixels; 0 uses every match",
        ))
        .param(seed_param())
        .output(PortSpec::one("camera", CameraArt::NAME, "K[R|t]"))
        .output(PortSpec::one(
            "report",
            ReportArt::NAME,
            "per-point reprojection errors, inliers and RMS",
        )),
        run_calibrate,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "two_view",
            "Relative pose and structure from two views with known K (book ch. 5): RANSAC on the \
             normalized 8-point F (Sampson distance in pixels, or the book's algebraic error), \
             E = KᵀFK, the four (R, t) and cheirality, triangulation. Camera a is K[I|0]; |t| = 1.",
        )
        .input(PortSpec::one(
            "points_a",
            Points2dArt::NAME,
            "points in view a",
        ))
        .input(PortSpec::one(
            "points_b",
            Points2dArt::NAME,
            "the same points in view b",
        ))
        .input(PortSpec::one(
            "intrinsics",
            IntrinsicsArt::NAME,
            "K of both views",
        ))
        .param(threshold_param(
            1.0,
            "RANSAC inlier threshold (Sampson distance, pixels)",
        ))
        .param(ParamSpec::optional(
            "residual",
            ParamType::Enum(&["sampson", "algebraic"]),
            ParamValue::Str("sampson".into()),
            "RANSAC residual",
        ))
        .param(seed_param())
        .output(PortSpec::one(
            "camera_b",
            CameraArt::NAME,
            "K[R|t] of view b",
        ))
        .output(PortSpec::one(
            "points3d",
            Points3dArt::NAME,
            "triangulated inliers",
        ))
        .output(PortSpec::one(
            "inliers",
            IndicesArt::NAME,
            "input index of each 3D point",
        ))
        .output(PortSpec::one("report", ReportArt::NAME, "figures")),
        run_two_view,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "write_camera",
            "Writes a camera as JSON {\"K\": [[3×3]], \"R\": [[3×3]], \"t\": [3], \"width\"?, \
             \"height\"?}, rows first, mapping X to K(RX + t).",
        )
        .input(PortSpec::one("camera", CameraArt::NAME, "the camera"))
        .param(path_out("JSON file")),
        |ctx| {
            let cam = &ctx.input::<CameraArt>("camera")?.0;
            write_json(ctx, cam)
        },
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "write_intrinsics",
            "Writes camera intrinsics K as the book's g7cam.txt (3×3, rows), or JSON (with \
             the image size) when the name ends in .json; what `read_intrinsics` reads.",
        )
        .input(PortSpec::one("intrinsics", IntrinsicsArt::NAME, "K"))
        .param(path_out("g7cam.txt-style K file, or .json")),
        |ctx| {
            let k = &ctx.input::<IntrinsicsArt>("intrinsics")?.0;
            Ok(formats::write_intrinsics(
                &crate::output_path(ctx, "path")?,
                k,
            )?)
        },
    ));
    r.register_node(FnNode::new(
        NodeSpec::new("write_report", "Writes any report as pretty JSON.")
            .threads(vfxgraph_engine::Threads::One)
            .input(PortSpec::one("report", ReportArt::NAME, "the report"))
            .param(path_out("JSON file")),
        |ctx| {
            let rep = &ctx.input::<ReportArt>("report")?.0;
            write_json(ctx, rep)
        },
    ));
}

fn write_json<T: serde::Serialize>(ctx: &Context<'_>, value: &T) -> Result<(), NodeError> {
    let path = ctx.path("path");
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| NodeError::msg(format!("cannot create {}: {e}", parent.display())))?;
    }
    atomic_write(&path, text.as_bytes())
        .map_err(|e| NodeError::msg(format!("cannot write {}: {e}", path.display())))
}

fn ransac_params(ctx: &Context<'_>) -> Option<RansacParams> {
    let t = ctx.params().f64("ransac_threshold_px");
    (t > 0.0).then(|| RansacParams::with_threshold(t))
}

fn rng(ctx: &Context<'_>) -> Pcg64 {
    Pcg64::seed_from_u64(ctx.params().i64("seed") as u64)
}

fn run_calibrate(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p3 = &ctx.input::<Points3dArt>("points3d")?.0;
    let p2 = &ctx.input::<Points2dArt>("points2d")?.0;
    let method = match ctx.params().str("method") {
        "dlt" => CalibrationMethod::Dlt,
        "tsai" => CalibrationMethod::Tsai,
        _ => CalibrationMethod::Restricted,
    };
    let pp = ctx.params().f64s("principal_point");
    let principal_point = match (method, pp.as_slice()) {
        (_, [u, v]) => Some(nalgebra::Point2::new(*u, *v)),
        (CalibrationMethod::Tsai, _) => {
            return Err(NodeError::msg(
                "method tsai needs `principal_point: [u0, v0]` (pixels)",
            ))
        }
        (_, []) => None,
        _ => return Err(NodeError::msg("`principal_point` is [u0, v0]")),
    };
    let opts = CalibrationOptions {
        method,
        principal_point,
        ransac: ransac_params(ctx),
        ..Default::default()
    };
    let (camera, report) = calibrate_camera(&p3.0, &p2.0, &opts, &mut rng(ctx))?;
    ctx.output("camera", CameraArt(camera));
    ctx.output("report", ReportArt(serde_json::to_value(&report)?));
    Ok(())
}

fn run_two_view(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let a = &ctx.input::<Points2dArt>("points_a")?.0;
    let b = &ctx.input::<Points2dArt>("points_b")?.0;
    let k = &ctx.input::<IntrinsicsArt>("intrinsics")?.0;
    let mut opts = TwoViewOptions::default();
    if let Some(r) = ransac_params(ctx) {
        opts.ransac = r;
    }
    if ctx.params().str("residual") == "algebraic" {
        opts.residual = EpipolarResidual::Algebraic;
    }
    let rec = reconstruct_two_view(&a.0, &b.0, k, k, &opts, &mut rng(ctx))?;
    ctx.output("camera_b", CameraArt(rec.camera_b.clone()));
    ctx.output("points3d", Points3dArt(rec.points3d.clone()));
    ctx.output("inliers", IndicesArt(rec.point_indices.clone()));
    ctx.output("report", ReportArt(serde_json::to_value(&rec.report)?));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, Value};
    use vfxgraph_vision::{synthetic, Camera, Points2d, Points3d};

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
        let rep = ctx.take_output::<ReportArt>("report").unwrap().0;
        assert!(rep["rms"].as_f64().unwrap() < 1.0, "{rep}");
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
        let pts3 = vfxgraph_vision::Points3d(vec![nalgebra::Point3::new(0.0, 0.0, 1.0); 3]);
        let pts2 = vfxgraph_vision::Points2d(vec![nalgebra::Point2::new(0.0, 0.0); 3]);
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
        write_json(&ctx, &ctx.input::<CameraArt>("camera").unwrap().0).unwrap();
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
