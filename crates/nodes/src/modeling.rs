//! Modeling nodes (book chapter 8): `read_marks`, `point_cloud_calibrate`.

use vfxgraph_engine::{Mode, NodeSpec, Registry};
use vfxgraph_geometry::formats::marked_points::{
    read_marked_points, write_marked_points, MarkedPoints,
};
use vfxgraph_geometry::modeling::point_cloud_calibrate;

use crate::artifacts::{json_artifact, CameraPathArt, IntrinsicsArt, Points3dArt, ReportArt};

json_artifact!(
    /// Points marked by hand on several frames (`marks`).
    MarkedPointsArt(MarkedPoints),
    "marks",
    "The same n scene points marked, in the same order, on several frames (book chapter 8)."
);

/// Registers the artifact and nodes of this module.
pub fn register(r: &mut Registry) {
    register_json_artifacts(r);
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
        .output_of::<MarkedPointsArt>("marks", "the marks"),
        |ctx| {
            let marks = read_marked_points(&ctx.path("path"))?;
            ctx.output("marks", MarkedPointsArt(marks));
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
        .input_of::<MarkedPointsArt>("marks", "the marks"),
        |ctx| {
            let marks = &ctx.input::<MarkedPointsArt>("marks")?.0;
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
        .input_of::<MarkedPointsArt>("marks", "the marked points")
        .input_of::<CameraPathArt>(
            "cameras",
            "the solved cameras (K from the path unless `intrinsics` is connected)",
        )
        .optional_input_of::<IntrinsicsArt>("intrinsics", "K, when the path carries none")
        .output_of::<Points3dArt>("points3d", "one world point per marked point")
        .output_of::<ReportArt>(
            "report",
            "frames used, the pair each point came from, per-point RMS and per-mark errors",
        ),
        |ctx| {
            let marks = &ctx.input::<MarkedPointsArt>("marks")?.0;
            let path = &ctx.input::<CameraPathArt>("cameras")?.0;
            let k = ctx
                .input_opt::<IntrinsicsArt>("intrinsics")?
                .map(|k| k.0.clone());
            let (points, report) = point_cloud_calibrate(marks, path, k.as_ref())?;
            let mut rep = serde_json::to_value(&report)?;
            rep["points"] = serde_json::to_value(&points)?;
            ctx.output("points3d", Points3dArt(points));
            ctx.output("report", ReportArt(rep));
            Ok(())
        },
    );
}
