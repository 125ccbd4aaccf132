//! Nodes for making a synthetic plate with ground truth (book ch. 10 and `tests/plate_shot.rs`):
//! `synthetic_camera_path` (a smooth orbit/dolly around a target: the true cameras a plate is
//! rendered along) and `project_marks` (the marks a user would click on a few frames, simulated
//! by projecting known 3-D points with the true cameras and rounding to whole pixels, in the
//! book's marked-points form of chapter 8).

use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, Out, Registry, Threads};
use vfxgraph_geometry::camera_path::{
    project_marks, synthetic_path, ProjectMarksOptions, SyntheticPathOptions,
};
use vfxgraph_params::Options;

use crate::artifacts::{CameraPathArt, IntrinsicsArt};
use crate::modeling::MarkedPointsArt;

/// `project_marks`' params: the points and frames, then [`ProjectMarksOptions`].
#[derive(Default, Options)]
struct ProjectMarksNodeOptions {
    /// the scene points, x y z of each in turn
    #[param(required)]
    points: Vec<f64>,
    /// the frames marked (whole numbers)
    #[param(required)]
    frames: Vec<f64>,
    #[param(flatten)]
    marks: ProjectMarksOptions,
}

const CAMERAS_OUT: Out<CameraPathArt> = Out::new("cameras", "the true cameras, with K");
const INTRINSICS: Out<IntrinsicsArt> = Out::new("intrinsics", "K and the image size");
const CAMERAS: In<CameraPathArt> = In::new("cameras", "the true cameras (with K)");
const MARKS: Out<MarkedPointsArt> = Out::new("marks", "the marks");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "synthetic_camera_path",
            "A smooth synthetic camera path with known truth: the camera orbits a target about \
             the vertical (+y) axis from azimuth `start` through `sweep` degrees (eased in and \
             out), its distance going linearly from `radius` to `radius_end` (a dolly) and its \
             height following `height` + `crane`·sin(πs), always looking at the target (image \
             y down). Frames `first_frame`… `first_frame + frames − 1`. Outputs the path (with \
             K: focal `focal` px, principal point at the image centre; with `zoom` ≠ 1 each \
             frame's own focal length, eased from `focal` to `zoom`·`focal`) and K alone.",
        )
        .threads(Threads::One)
        .mode(Mode::Once)
        .options::<SyntheticPathOptions>()
        .output(CAMERAS_OUT)
        .output(INTRINSICS),
        run_synthetic_camera_path,
    );
    r.register_fn(
        NodeSpec::new(
            "project_marks",
            "Simulated user clicks (book chapter 8's marked points): the 3-D `points` projected \
             by the true `cameras` into each of `frames`, rounded to whole pixels (or not, with \
             `round: false`). Every point must be in front of every chosen camera.",
        )
        .mode(Mode::Once)
        .options::<ProjectMarksNodeOptions>()
        .input(CAMERAS)
        .output(MARKS),
        run_project_marks,
    );
}

fn run_synthetic_camera_path(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let (path, k) = synthetic_path(&ctx.options()?)?;
    ctx.set(CAMERAS_OUT, CameraPathArt(path));
    ctx.set(INTRINSICS, IntrinsicsArt(k));
    Ok(())
}

fn run_project_marks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: ProjectMarksNodeOptions = ctx.options()?;
    let path = &ctx.get(CAMERAS)?.0;
    let marks = project_marks(path, &o.points, &o.frames, &o.marks)?;
    ctx.set(MARKS, MarkedPointsArt(marks));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, ParamValue, Value};

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
