//! Nodes for making a synthetic plate with ground truth (book ch. 10 and issue 9's plate test):
//! `synthetic_camera_path` (a smooth orbit/dolly around a target: the true cameras a plate is
//! rendered along) and `project_marks` (the marks a user would click on a few frames, simulated
//! by projecting known 3-D points with the true cameras and rounding to whole pixels, in the
//! book's marked-points form of chapter 8).

use nalgebra::{Point2, Point3, Vector3};
use vfxgraph_engine::{
    ArtifactType, Context, Mode, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, PortSpec,
    Registry, Threads,
};
use vfxgraph_vision::camera_path::{orbit_path, Orbit};
use vfxgraph_vision::formats::{MarkedFrame, MarkedPoints};
use vfxgraph_vision::{Camera, Intrinsics, Points2d};

use crate::artifacts::{CameraPathArt, IntrinsicsArt};
use crate::modeling::MarkedPointsArt;
use crate::FnNode;

fn float(name: &'static str, min: f64, max: f64, default: f64, doc: &'static str) -> ParamSpec {
    ParamSpec::optional(
        name,
        ParamType::Float { min, max },
        ParamValue::Float(default),
        doc,
    )
}

fn floats(name: &'static str, len: Option<usize>, default: &[f64], doc: &'static str) -> ParamSpec {
    ParamSpec::optional(
        name,
        ParamType::FloatList { len },
        ParamValue::List(default.iter().map(|v| ParamValue::Float(*v)).collect()),
        doc,
    )
}

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_node(FnNode::new(
        NodeSpec::new(
            "synthetic_camera_path",
            "A smooth synthetic camera path with known truth: the camera orbits a target about \
             the vertical (+y) axis from azimuth `start` through `sweep` degrees (eased in and \
             out), its distance going linearly from `radius` to `radius_end` (a dolly) and its \
             height following `height` + `crane`·sin(πs), always looking at the target (image \
             y down). Frames `first_frame`… `first_frame + frames − 1`. Outputs the path (with \
             K: focal `focal` px, principal point at the image centre) and K alone.",
        )
        .threads(Threads::One)
        .mode(Mode::Once)
        .param(ParamSpec::optional(
            "frames",
            ParamType::Int {
                min: 1,
                max: 100_000,
            },
            ParamValue::Int(40),
            "number of frames",
        ))
        .param(ParamSpec::optional(
            "first_frame",
            ParamType::Int {
                min: 0,
                max: 1 << 40,
            },
            ParamValue::Int(1),
            "number of the first frame",
        ))
        .param(floats(
            "target",
            Some(3),
            &[0.0, 0.0, 0.0],
            "the point looked at",
        ))
        .param(float(
            "radius",
            1e-6,
            1e9,
            4.0,
            "horizontal distance to the target's axis at the first frame",
        ))
        .param(float(
            "radius_end",
            1e-6,
            1e9,
            4.0,
            "…at the last frame (a dolly)",
        ))
        .param(float(
            "height",
            -1e9,
            1e9,
            1.5,
            "camera height above the target",
        ))
        .param(float(
            "crane",
            -1e9,
            1e9,
            0.0,
            "extra height at mid-shot (sine over the shot)",
        ))
        .param(float(
            "start",
            -1e4,
            1e4,
            0.0,
            "azimuth of the first camera, degrees (0: on +z of the target)",
        ))
        .param(float(
            "sweep",
            -1e4,
            1e4,
            30.0,
            "azimuth swept over the shot, degrees",
        ))
        .param(float(
            "focal",
            1e-3,
            1e7,
            400.0,
            "focal length, pixels (f1 = f2)",
        ))
        .param(ParamSpec::optional(
            "width",
            ParamType::Int { min: 1, max: 65536 },
            ParamValue::Int(320),
            "image width, pixels",
        ))
        .param(ParamSpec::optional(
            "height_px",
            ParamType::Int { min: 1, max: 65536 },
            ParamValue::Int(240),
            "image height, pixels",
        ))
        .output(PortSpec::one(
            "cameras",
            CameraPathArt::NAME,
            "the true cameras, with K",
        ))
        .output(PortSpec::one(
            "intrinsics",
            IntrinsicsArt::NAME,
            "K and the image size",
        )),
        run_synthetic_camera_path,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "project_marks",
            "Simulated user clicks (book chapter 8's marked points): the 3-D `points` projected \
             by the true `cameras` into each of `frames`, rounded to whole pixels (or not, with \
             `round: false`). Every point must be in front of every chosen camera.",
        )
        .mode(Mode::Once)
        .param(ParamSpec::required(
            "points",
            ParamType::FloatList { len: None },
            "the scene points, x y z of each in turn",
        ))
        .param(ParamSpec::required(
            "frames",
            ParamType::FloatList { len: None },
            "the frames marked (whole numbers)",
        ))
        .param(ParamSpec::optional(
            "round",
            ParamType::Bool,
            ParamValue::Bool(true),
            "round to whole pixels, as a click is",
        ))
        .input(PortSpec::one(
            "cameras",
            CameraPathArt::NAME,
            "the true cameras (with K)",
        ))
        .output(PortSpec::one("marks", MarkedPointsArt::NAME, "the marks")),
        run_project_marks,
    ));
}

fn run_synthetic_camera_path(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p = ctx.params();
    let t = p.f64s("target");
    let (w, h) = (p.i64("width") as u32, p.i64("height_px") as u32);
    let f = p.f64("focal");
    let k = Intrinsics::new(f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0).with_size(w, h);
    let orbit = Orbit {
        target: Vector3::new(t[0], t[1], t[2]),
        radius: p.f64("radius"),
        radius_end: p.f64("radius_end"),
        height: p.f64("height"),
        crane: p.f64("crane"),
        start: p.f64("start"),
        sweep: p.f64("sweep"),
        frames: p.i64("frames") as usize,
        first_frame: p.i64("first_frame") as usize,
    };
    let path = orbit_path(&orbit, &k)?;
    ctx.output("cameras", CameraPathArt(path));
    ctx.output("intrinsics", IntrinsicsArt(k));
    Ok(())
}

fn run_project_marks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p = ctx.params();
    let coords = p.f64s("points");
    if coords.is_empty() || coords.len() % 3 != 0 {
        return Err(NodeError::msg(format!(
            "`points` needs x y z per point: {} numbers is not a positive multiple of 3",
            coords.len()
        )));
    }
    let points: Vec<Point3<f64>> = coords
        .chunks(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect();
    let round = p.bool("round");
    let frames = p.f64s("frames");
    let path = &ctx.input::<CameraPathArt>("cameras")?.0;
    let k = path
        .intrinsics
        .clone()
        .ok_or_else(|| NodeError::msg("the camera path carries no intrinsics K"))?;
    let mut marks = MarkedPoints::default();
    for &f in &frames {
        if !(f >= 0.0 && f.fract() == 0.0) {
            return Err(NodeError::msg(format!(
                "`frames`: {f} is not a frame number"
            )));
        }
        let f = f as usize;
        let pose = path
            .frames
            .iter()
            .find(|p| p.frame == f)
            .ok_or_else(|| NodeError::msg(format!("the camera path has no frame {f}")))?;
        let cam = Camera::new(k.clone(), pose.pose.r, pose.pose.t);
        let mut px = Vec::with_capacity(points.len());
        for (i, x) in points.iter().enumerate() {
            if cam.depth(x) <= 0.0 {
                return Err(NodeError::msg(format!(
                    "point {i} is behind the camera of frame {f}"
                )));
            }
            let q = cam.project(x)?;
            px.push(if round {
                Point2::new(q.x.round(), q.y.round())
            } else {
                q
            });
        }
        marks.frames.push(MarkedFrame {
            frame: f,
            points: Points2d(px),
        });
    }
    ctx.output("marks", MarkedPointsArt(marks));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, Value};

    fn path(set: &[(&str, ParamValue)]) -> Result<(CameraPathArt, IntrinsicsArt), NodeError> {
        let sp = spec("synthetic_camera_path");
        let ps = params(&sp, set);
        let dir = std::env::temp_dir();
        let mut ctx = Context::for_test(&sp, &ps, &dir, None, vec![]);
        run_synthetic_camera_path(&mut ctx)?;
        Ok((
            ctx.take_output::<CameraPathArt>("cameras").unwrap(),
            ctx.take_output::<IntrinsicsArt>("intrinsics").unwrap(),
        ))
    }

    fn list(v: &[f64]) -> ParamValue {
        ParamValue::List(v.iter().map(|x| ParamValue::Float(*x)).collect())
    }

    #[test]
    fn path_then_marks() {
        let (cams, k) = path(&[
            ("frames", ParamValue::Int(10)),
            ("target", list(&[0.0, 0.2, 0.0])),
            ("sweep", ParamValue::Float(20.0)),
        ])
        .unwrap();
        assert_eq!(cams.0.frames.len(), 10);
        assert_eq!(cams.0.frames[0].frame, 1);
        assert_eq!(cams.0.intrinsics.as_ref(), Some(&k.0));
        assert_eq!(
            (k.0.width, k.0.height, k.0.u0),
            (Some(320), Some(240), 159.5)
        );
        let sp = spec("project_marks");
        let dir = std::env::temp_dir();
        let run = |set: &[(&str, ParamValue)]| {
            let ps = params(&sp, set);
            let mut ctx = Context::for_test(
                &sp,
                &ps,
                &dir,
                None,
                vec![("cameras", InputValue::One(Value::new(cams.clone())))],
            );
            run_project_marks(&mut ctx)
                .map(|_| ctx.take_output::<MarkedPointsArt>("marks").unwrap())
        };
        let m = run(&[
            ("points", list(&[0.0, 0.2, 0.0, 0.5, 0.0, 0.3])),
            ("frames", list(&[1.0, 5.0, 10.0])),
        ])
        .unwrap();
        assert_eq!(m.0.frames.len(), 3);
        assert_eq!(m.0.frames[1].frame, 5);
        // The target projects to the image centre (159.5, 119.5): the click is a whole pixel
        // next to it.
        let c = m.0.frames[0].points.0[0];
        assert!(
            (c.x - 159.5).abs() <= 0.5 + 1e-9 && (c.y - 119.5).abs() <= 0.5 + 1e-9,
            "{c}"
        );
        assert!(m.0.frames.iter().all(|f| f
            .points
            .0
            .iter()
            .all(|p| p.x.fract() == 0.0 && p.y.fract() == 0.0)));
        for (set, want) in [
            (
                vec![("points", list(&[0.0, 0.0])), ("frames", list(&[1.0]))],
                "multiple of 3",
            ),
            (
                vec![
                    ("points", list(&[0.0, 0.0, 0.0])),
                    ("frames", list(&[11.0])),
                ],
                "no frame 11",
            ),
            (
                vec![("points", list(&[0.0, 0.0, 0.0])), ("frames", list(&[1.5]))],
                "not a frame",
            ),
            (
                vec![("points", list(&[0.0, 0.0, 9.0])), ("frames", list(&[1.0]))],
                "behind the camera",
            ),
        ] {
            let e = run(&set).unwrap_err();
            assert!(e.message.contains(want), "{e}");
        }
    }
}
