//! Bundle adjustment nodes (book §7.7): `bundle_adjust`, `read_cameras`.

use vfxgraph_bundle::{adjust_sequence, SequenceAdjustOptions};
use vfxgraph_engine::{In, Mode, NodeSpec, OptIn, Out, Registry};
use vfxgraph_geometry::formats;

use crate::artifacts::{CameraPathArt, IntrinsicsArt, PointCloudArt, ReportArt};
use crate::tracking::TracksArt;

const CAMERAS: In<CameraPathArt> = In::new("cameras", "initial cameras");
const POINTS: In<PointCloudArt> = In::new("points", "initial points (with track ids)");
const TRACKS: In<TracksArt> = In::new("tracks", "the observations");
const INTRINSICS: In<IntrinsicsArt> = In::new("intrinsics", "K shared by every frame");
const CAMERAS_OUT: Out<CameraPathArt> = Out::new("cameras", "refined cameras");
const POINTS_OUT: Out<PointCloudArt> = Out::new("points", "refined points, errors filled in");
const INTRINSICS_OUT: Out<IntrinsicsArt> = Out::new("intrinsics", "K (refined if asked)");
const REPORT: Out<ReportArt> = Out::new(
    "report",
    "initial/final cost and RMS, iterations, termination, per-camera and per-point error",
);

const READ_K: OptIn<IntrinsicsArt> = OptIn::new("intrinsics", "K to attach to the path");
const READ_CAMERAS: Out<CameraPathArt> = Out::new("cameras", "one [R|t] per frame");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "bundle_adjust",
            "Sparse bundle adjustment of a shot (book §7.7): refines every camera of the path \
             and every point of the cloud against the tracks' observations by Levenberg–Marquardt \
             on the Schur complement (dense or sparse Cholesky, or PCG), with an optional robust \
             loss. The first camera and the first baseline's scale fix the gauge.",
        )
        .mode(Mode::Once)
        .input(CAMERAS)
        .input(POINTS)
        .input(TRACKS)
        .input(INTRINSICS)
        .options::<SequenceAdjustOptions>()
        .output(CAMERAS_OUT)
        .output(POINTS_OUT)
        .output(INTRINSICS_OUT)
        .output(REPORT),
        |ctx| {
            let o: SequenceAdjustOptions = ctx.options()?;
            let out = adjust_sequence(
                &ctx.get(CAMERAS)?.0,
                &ctx.get(POINTS)?.0,
                &ctx.get(TRACKS)?.0,
                &ctx.get(INTRINSICS)?.0,
                o.refine_intrinsics,
                &o.solver_options(),
            )?;
            tracing::info!(
                "{}: adjustment took {:.3} s",
                ctx.node_id(),
                out.report.seconds
            );
            let mut report = serde_json::to_value(&out.report)?;
            // The per-step log is for benchmarks; keep the artifact small.
            if let Some(o) = report.as_object_mut() {
                o.remove("steps");
            }
            ctx.set(CAMERAS_OUT, CameraPathArt(out.path));
            ctx.set(POINTS_OUT, PointCloudArt(out.cloud));
            ctx.set(INTRINSICS_OUT, IntrinsicsArt(out.intrinsics));
            ctx.set(REPORT, ReportArt(report));
            Ok(())
        },
    );
    r.register_fn(
        NodeSpec::new(
            "read_cameras",
            "Reads a camera path: the book's cameras file (`Frame i`, R rows, t) or its JSON form. \
             With `intrinsics` connected, the path carries that K (the book's file has none).",
        )
        .mode(Mode::Once)
        .input(READ_K)
        .input_file_param("path", "cameras file")
        .output(READ_CAMERAS),
        |ctx| {
            let mut path = formats::read_cameras(&ctx.path("path"))?;
            if let Some(k) = ctx.get(READ_K)? {
                path.intrinsics = Some(k.0.clone());
            }
            ctx.set(READ_CAMERAS, CameraPathArt(path));
            Ok(())
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use vfxgraph_engine::{Context, InputValue, Params, Value};
    use vfxgraph_geometry::camera::Pose;
    use vfxgraph_geometry::formats::{CameraPath, FramePose};
    use vfxgraph_geometry::points::PointCloud;
    use vfxgraph_klt::{Track, Tracks};

    /// Exact observations from a known path; a perturbed point cloud; the node must bring the
    /// reprojection error to ~0 and report it.
    #[test]
    fn bundle_adjust_node_refines_points_to_exact_observations() {
        let k = vfxgraph_geometry::Intrinsics::new(700.0, 700.0, 320.0, 240.0);
        let poses: Vec<Pose> = (0..5)
            .map(|i| Pose {
                r: nalgebra::Matrix3::identity(),
                t: Vector3::new(-0.2 * i as f64, 0.0, 0.0),
            })
            .collect();
        let world: Vec<Vector3<f64>> = (0..40)
            .map(|j| {
                let a = j as f64;
                Vector3::new(
                    (a * 0.37).sin() * 2.0,
                    (a * 0.71).cos(),
                    5.0 + (a * 0.13).sin(),
                )
            })
            .collect();
        let tracks = Tracks {
            frames: (0..5).collect(),
            slots: world.len(),
            image_size: None,
            tracks: world
                .iter()
                .enumerate()
                .map(|(id, x)| Track {
                    id: 100 + id as u64,
                    slot: id,
                    first: 0,
                    points: poses
                        .iter()
                        .map(|p| {
                            let c = p.r * x + p.t;
                            [k.f1 * c.x / c.z + k.u0, k.f2 * c.y / c.z + k.v0]
                        })
                        .collect(),
                    lost: None,
                })
                .collect(),
        };
        let path = CameraPath {
            frames: poses
                .iter()
                .enumerate()
                .map(|(i, p)| FramePose {
                    frame: i,
                    pose: p.clone(),
                    focal: None,
                })
                .collect(),
            intrinsics: None,
        };
        let cloud = PointCloud {
            points: world
                .iter()
                .map(|x| [x.x + 0.03, x.y, x.z - 0.05])
                .collect(),
            track_ids: (0..world.len() as u64).map(|i| 100 + i).collect(),
            errors: vec![],
            ..Default::default()
        };
        let r = crate::registry();
        let spec = r.node("bundle_adjust").unwrap().spec().clone();
        let params = Params::new(
            spec.params
                .iter()
                .map(|p| (p.name.to_string(), p.default.clone().unwrap()))
                .collect(),
        );
        let mut ctx = Context::for_test(
            &spec,
            &params,
            std::path::Path::new("."),
            None,
            vec![
                ("cameras", InputValue::One(Value::new(CameraPathArt(path)))),
                ("points", InputValue::One(Value::new(PointCloudArt(cloud)))),
                ("tracks", InputValue::One(Value::new(TracksArt(tracks)))),
                ("intrinsics", InputValue::One(Value::new(IntrinsicsArt(k)))),
            ],
        );
        let run = r.node("bundle_adjust").unwrap();
        run.run(&mut ctx).unwrap();
        let rep = ctx.take_output::<ReportArt>("report").unwrap().0;
        assert!(rep["initial_rms"].as_f64().unwrap() > 1.0, "{rep}");
        assert!(rep["final_rms"].as_f64().unwrap() < 1e-3, "{rep}");
        let out = ctx.take_output::<PointCloudArt>("points").unwrap().0;
        assert_eq!(out.track_ids[0], 100);
        assert!(out.errors.iter().all(|e| *e < 1e-3));
    }
}
