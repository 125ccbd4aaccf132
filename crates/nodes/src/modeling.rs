//! Modeling nodes (book chapter 8): `read_marks`, `point_cloud_calibrate`.

use vfxgraph_engine::{In, Mode, NodeSpec, OptIn, Out, Registry};
use vfxgraph_geometry::formats::marked_points::{
    read_marked_points, write_marked_points, MarkedPoints,
};
use vfxgraph_geometry::modeling::{point_cloud_calibrate, PointCloudReport};
use vfxgraph_geometry::Points3d;

use crate::artifacts::{json_artifact, CameraPathArt, IntrinsicsArt, Points3dArt, ReportArt};

json_artifact!(
    /// Points marked by hand on several frames (`marks`).
    MarkedPointsArt(MarkedPoints),
    "marks",
    "The same n scene points marked, in the same order, on several frames (book chapter 8)."
);

const MARKS_OUT: Out<MarkedPointsArt> = Out::new("marks", "the marks");
const MARKS: In<MarkedPointsArt> = In::new("marks", "the marks");
const MARKED: In<MarkedPointsArt> = In::new("marks", "the marked points");
const CAMERAS: In<CameraPathArt> = In::new(
    "cameras",
    "the solved cameras (K from the path unless `intrinsics` is connected)",
);
const INTRINSICS: OptIn<IntrinsicsArt> = OptIn::new("intrinsics", "K, when the path carries none");
const POINTS3D: Out<Points3dArt> = Out::new("points3d", "one world point per marked point");
const REPORT: Out<ReportArt> = Out::new(
    "report",
    "frames used, the pair each point came from, per-point RMS and per-mark errors",
);

/// `point_cloud_calibrate`'s report: the calibration's figures and the points.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeasuredReport {
    /// Frames used, the pair each point came from, per-point RMS and per-mark errors.
    #[serde(flatten)]
    pub figures: PointCloudReport,
    /// One world point per marked point.
    pub points: Points3d,
}

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "read_marks",
            "Reads marked points: the book's `points2d.txt` (`Frame f` / `Npoints n` / n lines \
             `u v`) or its JSON form.",
        )
        .mode(Mode::Once)
        .threads(vfxgraph_engine::Threads::One)
        .memory(vfxgraph_engine::Memory::Fixed(256))
        .input_file_param("path", "marked-points file")
        .output(MARKS_OUT),
        |ctx| {
            let marks = read_marked_points(&ctx.path("path"))?;
            ctx.set(MARKS_OUT, MarkedPointsArt(marks));
            Ok(())
        },
    );
    r.register_fn(
        NodeSpec::new(
            "write_marks",
            "Writes marked points as the book's `points2d.txt`, or JSON when the name ends \
             in .json; what `read_marks` reads.",
        )
        .output_file_param("path", "marked-points file")
        .input(MARKS),
        |ctx| {
            let marks = &ctx.get(MARKS)?.0;
            Ok(write_marked_points(&ctx.path("path"), marks)?)
        },
    );
    r.register_fn(
        NodeSpec::new(
            "point_cloud_calibrate",
            "Point-cloud calibration (book chapter 8): each marked point triangulated from the \
             pair of marked frames with the least total reprojection error, refined by \
             Levenberg–Marquardt over all its marks with the cameras fixed.",
        )
        .mode(Mode::Once)
        .input(MARKED)
        .input(CAMERAS)
        .input(INTRINSICS)
        .output(POINTS3D)
        .output(REPORT),
        |ctx| {
            let marks = &ctx.get(MARKED)?.0;
            let path = &ctx.get(CAMERAS)?.0;
            let k = ctx.get(INTRINSICS)?.map(|k| k.0.clone());
            let (points, figures) = point_cloud_calibrate(marks, path, k.as_ref())?;
            let report = ReportArt::of(&MeasuredReport {
                figures,
                points: points.clone(),
            })?;
            ctx.set(POINTS3D, Points3dArt(points));
            ctx.set(REPORT, report);
            Ok(())
        },
    );
}
