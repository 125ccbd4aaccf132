//! Matchmove nodes (book chapter 7): `matchmove`, `relax`, `global_bundle_adjust`,
//! `write_cameras`, `plot_solve_error`. The algorithms and their params (the book's values as
//! defaults) live in `vfxgraph_geometry::matchmove`.

use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, OptIn, Out, Registry};
use vfxgraph_geometry::formats;
use vfxgraph_imaging::draw::svg::solve_error_svg;
use vfxgraph_matchmove::{
    adjust_path, matchmove_with_lens, relax_path, solve_progress, GlobalPathOptions,
    MatchmoveOptions, RelaxPathOptions, Solve,
};

use crate::artifacts::{CameraPathArt, IntrinsicsArt, PointCloudArt, ReportArt};
use crate::tracking::TracksArt;

/// A solve node's spec: `matchmove`'s (K optional), or one that refines a solved path
/// (`cameras_in`: K and the path required).
fn solve_node(name: &'static str, doc: &'static str, cameras_in: bool) -> NodeSpec {
    let spec = NodeSpec::new(name, doc).mode(Mode::Once).input(TRACKS);
    let spec = if cameras_in {
        spec.input(SHARED_K).input(SOLVED)
    } else {
        spec.input(START_K)
    };
    spec.output(CAMERAS_OUT).output(POINTS).output(SOLVE_REPORT)
}

fn set_solve(ctx: &mut Context<'_>, solve: Solve) -> Result<(), NodeError> {
    for s in &solve.report.stages {
        tracing::info!("{}: {} took {:.3} s", ctx.node_id(), s.stage, s.seconds);
    }
    ctx.set(
        SOLVE_REPORT,
        ReportArt(serde_json::to_value(&solve.report)?),
    );
    ctx.set(CAMERAS_OUT, CameraPathArt(solve.path));
    ctx.set(POINTS, PointCloudArt(solve.cloud));
    Ok(())
}

fn run_matchmove(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o = MatchmoveOptions {
        seed: ctx.seed(),
        ..ctx.options()?
    };
    let tracks = &ctx.get(TRACKS)?.0;
    let k = ctx.get(START_K)?.map(|k| &k.0);
    let k = o.lens.initial_intrinsics(k, tracks.image_size)?;
    let solve = matchmove_with_lens(tracks, &k, &o.lens, &o, &|stage, done, total| {
        ctx.progress(solve_progress(stage, done, total))
    })?;
    // What a person must check before trusting the cameras is said when the solve runs, as
    // well as kept in the report.
    for w in &solve.report.warnings {
        eprintln!("warning: node '{}': {w}", ctx.node_id());
    }
    set_solve(ctx, solve)
}

fn run_relax(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: RelaxPathOptions = ctx.options()?;
    let tracks = &ctx.get(TRACKS)?.0;
    let k = &ctx.get(SHARED_K)?.0;
    let path = &ctx.get(SOLVED)?.0;
    let solve = relax_path(tracks, k, path, &o.relax, o.score.score, &|done, total| {
        ctx.progress(done as f32 / total.max(1) as f32)
    })?;
    set_solve(ctx, solve)
}

fn run_global(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: GlobalPathOptions = ctx.options()?;
    let tracks = &ctx.get(TRACKS)?.0;
    let k = &ctx.get(SHARED_K)?.0;
    let path = &ctx.get(SOLVED)?.0;
    let solve = adjust_path(tracks, k, path, &o.global, o.score.score)?;
    set_solve(ctx, solve)
}

fn run_write_cameras(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: formats::WriteCamerasOptions = ctx.options()?;
    let path = ctx.path("path");
    let cams = &ctx.get(PATH)?.0;
    formats::write_camera_path(&path, cams, o.format)?;
    Ok(())
}

fn run_plot(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let report = &ctx.get(REPORT)?.0;
    let svg = solve_error_svg(report).map_err(NodeError::msg)?;
    crate::write_output(ctx, "path", svg.as_bytes())
}

const TRACKS: In<TracksArt> = In::new("tracks", "the feature tracks");
const SHARED_K: In<IntrinsicsArt> = In::new("intrinsics", "K, shared by every frame");
const SOLVED: In<CameraPathArt> = In::new(
    "cameras",
    "a solved path covering every frame of the tracks",
);
const START_K: OptIn<IntrinsicsArt> = OptIn::new(
    "intrinsics",
    "K and the lens shared by every frame: exact, or a start (focal: refine); optional \
             with focal: unknown and the image size",
);
const CAMERAS_OUT: Out<CameraPathArt> = Out::new("cameras", "K and [R|t] of every frame");
const POINTS: Out<PointCloudArt> = Out::new(
    "points",
    "the reconstructed points, with track ids, RMS errors over their inlier observations and \
     the frames of those (the solve's final inliers, within the report's inlier_tolerance)",
);
const SOLVE_REPORT: Out<ReportArt> = Out::new(
    "report",
    "per-frame RMS and inliers, per-track error, overall RMS, stage times, the book-style \
     score over all tracks",
);
const PATH: In<CameraPathArt> = In::new("cameras", "the path to write");
const REPORT: In<ReportArt> = In::new(
    "report",
    "the report of matchmove, relax or global_bundle_adjust",
);

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    let spec = solve_node(
        "matchmove",
        "The camera of every frame from feature tracks and K (book chapter 7): fragments \
         (§7.11), each fragment's best frame pair by RANSAC on F, E, cheirality and resection of \
         every frame (§7.2–7.6), resection and refinement cycles of bundle adjustment and \
         re-triangulation (§7.9), scale search and junction (§7.12), resection of frames no \
         fragment solved, then a robust global bundle adjustment. Fragments run in parallel.",
        false,
    )
    .seeded()
    .options::<MatchmoveOptions>();
    r.register_fn(spec, run_matchmove);

    let spec = solve_node(
        "relax",
        "The book's relaxation (§7.14): tracks longer than `min_run` frames become homologous \
         points triangulated from their best frame pair; then rounds of cycles of alternating \
         point and camera Levenberg–Marquardt with a shrinking inlier tolerance.",
        true,
    )
    .options::<RelaxPathOptions>();
    r.register_fn(spec, run_relax);

    let spec = solve_node(
        "global_bundle_adjust",
        "Robust bundle adjustment of a whole solved sequence: every track triangulated robustly, \
         all cameras and points adjusted together (sparse Schur LM, K fixed), outliers re-marked \
         at shrinking thresholds.",
        true,
    )
    .options::<GlobalPathOptions>();
    r.register_fn(spec, run_global);

    r.register_fn(
        NodeSpec::new(
            "write_cameras",
            "Writes a camera path: the book's cameras file (`Frame i`, R rows, t) or JSON (with K \
             when known). The write is atomic.",
        )
        .mode(Mode::Once)
        .output_file_param("path", "output file")
        .options::<formats::WriteCamerasOptions>()
        .input(PATH),
        run_write_cameras,
    );

    r.register_fn(
        NodeSpec::new(
            "plot_solve_error",
            "Plots a solve's report as SVG: reprojection RMS per frame and inliers per frame \
             (what a tracker's solve panel shows).",
        )
        .mode(Mode::Once)
        .output_file_param("path", "output .svg file")
        .input(REPORT),
        run_plot,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_matchmove::SolveReport;

    use vfxgraph_matchmove::synthetic::{synthetic_shot, ShotOptions};

    fn shot() -> vfxgraph_matchmove::synthetic::SyntheticShot {
        synthetic_shot(&ShotOptions {
            frames: 70,
            slots: 80,
            mean_track_length: 40.0,
            ..ShotOptions::default()
        })
    }

    /// Runs `matchmove` (with `min_frames: 30`) on a synthetic shot: the outcome and the
    /// `cameras` and `report` outputs when it succeeded.
    fn run_node(
        s: &vfxgraph_matchmove::synthetic::SyntheticShot,
    ) -> (
        Result<(), NodeError>,
        Option<CameraPathArt>,
        Option<ReportArt>,
    ) {
        run_node_with(s, &[])
    }

    /// [`run_node`] with more params set.
    fn run_node_with(
        s: &vfxgraph_matchmove::synthetic::SyntheticShot,
        set: &[(&str, ParamValue)],
    ) -> (
        Result<(), NodeError>,
        Option<CameraPathArt>,
        Option<ReportArt>,
    ) {
        let sp = spec("matchmove");
        let mut set = set.to_vec();
        set.push(("min_frames", ParamValue::Int(30)));
        let p = params(&sp, &set);
        let inputs = [
            (
                "tracks",
                InputValue::One(Value::new(TracksArt(s.tracks.clone()))),
            ),
            (
                "intrinsics",
                InputValue::One(Value::new(IntrinsicsArt(s.k.clone()))),
            ),
        ];
        let dir = std::env::temp_dir();
        let mut ctx = Context::for_test(&sp, &p, &dir, None, inputs.into_iter().collect());
        let r = run_matchmove(&mut ctx);
        let cams = ctx.take_output::<CameraPathArt>("cameras");
        let report = ctx.take_output::<ReportArt>("report");
        (r, cams, report)
    }

    /// The node solves a synthetic shot: every frame gets a finite camera with K attached, and
    /// the report's figures are at the noise level.
    #[test]
    fn matchmove_node_solves_a_synthetic_shot() {
        let s = shot();
        let (r, cams, report) = run_node(&s);
        r.unwrap();
        let cams = cams.unwrap().0;
        assert_eq!(cams.frames.len(), 70);
        assert_eq!(cams.intrinsics.as_ref(), Some(&s.k));
        assert!(cams.frames.iter().all(|f| f
            .pose
            .r
            .iter()
            .chain(f.pose.t.iter())
            .all(|v| v.is_finite())));
        let report: SolveReport = report.unwrap().parse().unwrap();
        let rms = report.overall_rms;
        assert!(rms < 1.0, "overall RMS {rms}");
        assert_eq!(report.frames.len(), 70);
        assert!(report.score.unwrap().median < 1.0);
    }

    /// A nodal pan solved as a moving camera (`solve: general`, no parallax) gives a clear
    /// error, never NaN cameras; the default (`solve: auto`) solves it as rotations
    /// (vfxgraph_matchmove::tripod) and its report says so.
    #[test]
    fn a_tripod_pan_is_a_clear_error_as_a_moving_camera_and_solved_as_a_pan() {
        let s = synthetic_shot(&ShotOptions {
            frames: 70,
            slots: 80,
            travel: 0.0,
            bob: 0.0,
            outlier_fraction: 0.0,
            ..ShotOptions::default()
        });
        let (r, cams, report) = run_node(&s);
        r.unwrap();
        let report: SolveReport = report.unwrap().parse().unwrap();
        assert!(report.rotation_only, "{report:?}");
        assert!(cams
            .unwrap()
            .0
            .frames
            .iter()
            .all(|f| f.pose.t.norm() == 0.0));
        let general = [("solve", ParamValue::Str("general".into()))];
        let err = run_node_with(&s, &general).0.unwrap_err().to_string();
        assert!(
            err.contains("parallax") || err.contains("rotation"),
            "{err}"
        );
    }

    /// Footage with too few tracks for a fragment gives a clear error naming the frames, never
    /// NaN cameras.
    #[test]
    fn too_few_tracks_is_a_clear_error() {
        let s = synthetic_shot(&ShotOptions {
            frames: 70,
            slots: 7,
            ..ShotOptions::default()
        });
        let (r, cams, _) = run_node(&s);
        let err = r.unwrap_err().to_string();
        assert!(err.contains("frames"), "{err}");
        assert!(cams.is_none());
    }
}
