//! Matchmove nodes (book chapter 7): `matchmove`, `relax`, `global_bundle_adjust`,
//! `write_cameras`, `plot_solve_error`. The algorithms live in `vfxgraph_vision::matchmove`;
//! every constant is a param with the book's value as default.

use vfxgraph_engine::{
    ArtifactType, Context, Mode, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, Params,
    PathRole, PortSpec, Registry,
};
use vfxgraph_vision::formats;
use vfxgraph_vision::matchmove::{
    adjust_path, global::RobustLoss, matchmove, relax_path, GlobalOptions, MatchmoveOptions,
    RelaxOptions, Solve,
};

use crate::artifacts::{CameraPathArt, IntrinsicsArt, PointCloudArt, ReportArt};
use crate::tracking::TracksArt;
use crate::FnNode;

fn float(name: &'static str, min: f64, max: f64, default: f64, doc: &'static str) -> ParamSpec {
    ParamSpec::optional(
        name,
        ParamType::Float { min, max },
        ParamValue::Float(default),
        doc,
    )
}

fn int(name: &'static str, min: i64, max: i64, default: i64, doc: &'static str) -> ParamSpec {
    ParamSpec::optional(
        name,
        ParamType::Int { min, max },
        ParamValue::Int(default),
        doc,
    )
}

fn floats(name: &'static str, default: &[f64], doc: &'static str) -> ParamSpec {
    ParamSpec::optional(
        name,
        ParamType::FloatList { len: None },
        ParamValue::List(default.iter().map(|v| ParamValue::Float(*v)).collect()),
        doc,
    )
}

/// The params of the global adjustment, shared by `matchmove` and `global_bundle_adjust`.
fn global_params(spec: NodeSpec) -> NodeSpec {
    spec.param(ParamSpec::optional(
        "loss",
        ParamType::Enum(&["none", "huber", "cauchy"]),
        ParamValue::Str("huber".into()),
        "robust loss of the global bundle adjustment",
    ))
    .param(float(
        "loss_scale",
        1e-6,
        1e3,
        1.0,
        "where the robust loss starts to down-weight, pixels",
    ))
    .param(floats(
        "outlier_thresholds",
        &[3.0, 1.5],
        "outlier thresholds of the successive global adjustment rounds, pixels",
    ))
    .param(float(
        "triangulation_tolerance",
        1e-3,
        1e4,
        10.0,
        "first triangulation of every track: observations farther than this are outliers, px",
    ))
    .param(int(
        "min_observations",
        2,
        100_000,
        3,
        "tracks with fewer inlier observations get no point",
    ))
    .param(int(
        "max_iterations",
        1,
        10_000,
        50,
        "Levenberg–Marquardt steps per adjustment",
    ))
}

fn global_options(p: &Params) -> Result<GlobalOptions, NodeError> {
    let thresholds = p.f64s("outlier_thresholds");
    if thresholds.iter().any(|t| t.is_nan() || *t <= 0.0) {
        return Err(NodeError::msg("`outlier_thresholds` must all be positive"));
    }
    Ok(GlobalOptions {
        loss: match p.str("loss") {
            "none" => RobustLoss::None,
            "cauchy" => RobustLoss::Cauchy,
            _ => RobustLoss::Huber,
        },
        loss_scale: p.f64("loss_scale"),
        thresholds,
        triangulation_tolerance: p.f64("triangulation_tolerance"),
        min_observations: p.i64("min_observations") as usize,
        max_iterations: p.i64("max_iterations") as usize,
    })
}

fn solve_outputs(spec: NodeSpec) -> NodeSpec {
    spec.output(PortSpec::one(
        "cameras",
        CameraPathArt::NAME,
        "K and [R|t] of every frame",
    ))
    .output(PortSpec::one(
        "points",
        PointCloudArt::NAME,
        "the reconstructed points, with track ids, RMS errors over their inlier observations and \
         the frames of those (the solve's final inliers, within the report's inlier_tolerance)",
    ))
    .output(PortSpec::one(
        "report",
        ReportArt::NAME,
        "per-frame RMS and inliers, per-track error, overall RMS, stage times, the book-style \
         score over all tracks",
    ))
}

fn solve_inputs(spec: NodeSpec) -> NodeSpec {
    spec.input(PortSpec::one(
        "tracks",
        TracksArt::NAME,
        "the feature tracks",
    ))
    .input(PortSpec::one(
        "intrinsics",
        IntrinsicsArt::NAME,
        "K, shared by every frame",
    ))
}

fn set_solve(ctx: &mut Context<'_>, solve: Solve) -> Result<(), NodeError> {
    ctx.output("report", ReportArt(serde_json::to_value(&solve.report)?));
    ctx.output("cameras", CameraPathArt(solve.path));
    ctx.output("points", PointCloudArt(solve.cloud));
    Ok(())
}

fn run_matchmove(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p = ctx.params();
    let mut o = MatchmoveOptions::default();
    o.fragments.min_frames = p.i64("min_frames") as usize;
    o.fragments.min_displacement = p.f64("min_displacement");
    o.fragments.min_features = p.i64("min_features") as usize;
    o.pair.min_displacement = p.f64("pair_min_displacement");
    o.pair.stride = p.i64("pair_stride") as usize;
    o.pair.epipolar_threshold = p.f64("epipolar_threshold");
    o.pair.ransac_iterations = p.i64("ransac_iterations") as usize;
    o.pair.resection_tolerance = p.f64("resection_tolerance");
    o.pair.max_k_difference = p.f64("max_k_difference");
    o.refine.tolerances = p.f64s("refine_tolerances");
    if o.refine.tolerances.iter().any(|t| t.is_nan() || *t <= 0.0) {
        return Err(NodeError::msg("`refine_tolerances` must all be positive"));
    }
    o.scale.min_scale = p.f64("scale_min");
    o.scale.max_scale = p.f64("scale_max");
    o.scale.step = p.f64("scale_step");
    o.scale.tolerance = p.f64("scale_tolerance");
    if o.scale.min_scale >= o.scale.max_scale {
        return Err(NodeError::msg("`scale_min` must be below `scale_max`"));
    }
    o.global = if p.bool("global_adjust") {
        Some(global_options(p)?)
    } else {
        None
    };
    o.score = p.bool("score");
    o.seed = ctx.seed();
    let tracks = &ctx.input::<TracksArt>("tracks")?.0;
    let k = &ctx.input::<IntrinsicsArt>("intrinsics")?.0;
    let solve = matchmove(tracks, k, &o, &|stage, done, total| {
        // Fragments are most of the work; the global adjustment the rest.
        let f = if stage == "fragments" {
            0.7 * done as f32 / total.max(1) as f32
        } else {
            0.7 + 0.3 * done as f32 / total.max(1) as f32
        };
        ctx.progress(f);
    })?;
    set_solve(ctx, solve)
}

fn run_relax(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p = ctx.params();
    let o = RelaxOptions {
        min_run: p.i64("min_run") as usize,
        agree_tolerance: p.f64("agree_tolerance"),
        rounds: p.i64("rounds") as usize,
        cycles: p.i64("cycles") as usize,
        initial_tolerance: p.f64("initial_tolerance"),
        tolerance_step: p.f64("tolerance_step"),
        lm_iterations: p.i64("lm_iterations") as usize,
        pair_stride: p.i64("pair_stride") as usize,
    };
    let score = p.bool("score");
    let tracks = &ctx.input::<TracksArt>("tracks")?.0;
    let k = &ctx.input::<IntrinsicsArt>("intrinsics")?.0;
    let path = &ctx.input::<CameraPathArt>("cameras")?.0;
    let solve = relax_path(tracks, k, path, &o, score, &|done, total| {
        ctx.progress(done as f32 / total.max(1) as f32)
    })?;
    set_solve(ctx, solve)
}

fn run_global(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p = ctx.params();
    let o = global_options(p)?;
    let score = p.bool("score");
    let tracks = &ctx.input::<TracksArt>("tracks")?.0;
    let k = &ctx.input::<IntrinsicsArt>("intrinsics")?.0;
    let path = &ctx.input::<CameraPathArt>("cameras")?.0;
    let solve = adjust_path(tracks, k, path, &o, score)?;
    set_solve(ctx, solve)
}

fn run_write_cameras(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let path = ctx.path("path");
    let cams = &ctx.input::<CameraPathArt>("cameras")?.0;
    let json = match ctx.params().str("format") {
        "json" => true,
        "book" => false,
        _ => formats::is_json(&path),
    };
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| NodeError::msg(format!("cannot create {}: {e}", parent.display())))?;
    }
    if json {
        formats::write_json(&path, cams)?;
    } else {
        formats::write_cameras(&path, cams)?;
    }
    Ok(())
}

fn run_plot(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let path = ctx.path("path");
    let report = &ctx.input::<ReportArt>("report")?.0;
    let svg = crate::plot::solve_error_svg(report).map_err(NodeError::msg)?;
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| NodeError::msg(format!("cannot create {}: {e}", parent.display())))?;
    }
    vfxgraph_engine::fsutil::atomic_write(&path, svg.as_bytes())
        .map_err(|e| NodeError::msg(format!("{}: {e}", path.display())))?;
    Ok(())
}

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    let spec = NodeSpec::new(
        "matchmove",
        "The camera of every frame from feature tracks and K (book chapter 7): fragments \
         (§7.11), each fragment's best frame pair by RANSAC on F, E, cheirality and resection of \
         every frame (§7.2–7.6), resection and refinement cycles of bundle adjustment and \
         re-triangulation (§7.9), scale search and junction (§7.12), resection of frames no \
         fragment solved, then a robust global bundle adjustment. Fragments run in parallel.",
    )
    .mode(Mode::Once)
    .seeded();
    let spec = solve_inputs(spec)
        .param(int(
            "min_frames",
            2,
            100_000,
            60,
            "a fragment has more frames than this (§7.11)",
        ))
        .param(float(
            "min_displacement",
            0.0,
            1e5,
            20.0,
            "…and its features moved this much since its base frame, px (§7.11)",
        ))
        .param(int(
            "min_features",
            6,
            100_000,
            30,
            "cut a fragment early rather than keep fewer features through it",
        ))
        .param(float(
            "pair_min_displacement",
            0.0,
            1e5,
            4.0,
            "candidate pairs moved more than this on average, px (§7.2)",
        ))
        .param(int(
            "pair_stride",
            1,
            10_000,
            6,
            "candidate frames of the pair search: every n-th (the book: 1, every pair)",
        ))
        .param(float(
            "epipolar_threshold",
            1e-3,
            1e3,
            1.5,
            "Sampson-distance threshold of the RANSAC on F, px",
        ))
        .param(int(
            "ransac_iterations",
            1,
            1_000_000,
            500,
            "most RANSAC iterations on F (adaptive below this)",
        ))
        .param(float(
            "resection_tolerance",
            1e-3,
            1e4,
            15.0,
            "resection (6-point DLT) RANSAC threshold, px (§7.3)",
        ))
        .param(float(
            "max_k_difference",
            0.0,
            1e6,
            100.0,
            "intrinsics-consistency test: largest entry difference of a frame's DLT K' from K",
        ))
        .param(floats(
            "refine_tolerances",
            &[10.0, 5.0, 3.0],
            "re-triangulation tolerances of the refinement cycles, px (§7.9)",
        ))
        .param(float(
            "scale_min",
            1e-9,
            1e9,
            1e-3,
            "smallest relative scale tried (§7.12)",
        ))
        .param(float(
            "scale_max",
            1e-9,
            1e9,
            100.0,
            "largest relative scale tried (§7.12)",
        ))
        .param(float(
            "scale_step",
            1.000_001,
            10.0,
            1.01,
            "ratio of the scale progression (§7.12)",
        ))
        .param(float(
            "scale_tolerance",
            1e-3,
            1e5,
            20.0,
            "a point agrees with a scale if its error is below this in every frame, px",
        ))
        .param(ParamSpec::optional(
            "global_adjust",
            ParamType::Bool,
            ParamValue::Bool(true),
            "finish with a robust bundle adjustment of the whole sequence",
        ))
        .param(ParamSpec::optional(
            "score",
            ParamType::Bool,
            ParamValue::Bool(true),
            "score the cameras against every track into the report",
        ));
    let spec = solve_outputs(global_params(spec));
    r.register_node(FnNode::new(spec, run_matchmove));

    let spec = NodeSpec::new(
        "relax",
        "The book's relaxation (§7.14): tracks longer than `min_run` frames become homologous \
         points triangulated from their best frame pair; then rounds of cycles of alternating \
         point and camera Levenberg–Marquardt with a shrinking inlier tolerance.",
    )
    .mode(Mode::Once);
    let spec = solve_inputs(spec)
        .input(PortSpec::one(
            "cameras",
            CameraPathArt::NAME,
            "a solved path covering every frame of the tracks",
        ))
        .param(int(
            "min_run",
            2,
            100_000,
            45,
            "tracks longer than this become homologous points",
        ))
        .param(float(
            "agree_tolerance",
            1e-3,
            1e4,
            10.0,
            "a frame agrees with a point's triangulation below this error, px",
        ))
        .param(int("rounds", 0, 1000, 9, "rounds"))
        .param(int("cycles", 1, 1000, 10, "point/camera cycles per round"))
        .param(float(
            "initial_tolerance",
            1e-3,
            1e4,
            10.0,
            "inlier tolerance of the first round, px",
        ))
        .param(float(
            "tolerance_step",
            0.0,
            1e4,
            1.0,
            "its decrease per round, px",
        ))
        .param(int(
            "lm_iterations",
            1,
            1000,
            3,
            "LM iterations per point or camera optimization",
        ))
        .param(int(
            "pair_stride",
            1,
            10_000,
            4,
            "pair search over every n-th frame of a track",
        ))
        .param(ParamSpec::optional(
            "score",
            ParamType::Bool,
            ParamValue::Bool(true),
            "score the cameras against every track into the report",
        ));
    r.register_node(FnNode::new(solve_outputs(spec), run_relax));

    let spec = NodeSpec::new(
        "global_bundle_adjust",
        "Robust bundle adjustment of a whole solved sequence: every track triangulated robustly, \
         all cameras and points adjusted together (sparse Schur LM, K fixed), outliers re-marked \
         at shrinking thresholds.",
    )
    .mode(Mode::Once);
    let spec = solve_inputs(spec)
        .input(PortSpec::one(
            "cameras",
            CameraPathArt::NAME,
            "a solved path covering every frame of the tracks",
        ))
        .param(ParamSpec::optional(
            "score",
            ParamType::Bool,
            ParamValue::Bool(true),
            "score the cameras against every track into the report",
        ));
    r.register_node(FnNode::new(solve_outputs(global_params(spec)), run_global));

    r.register_node(FnNode::new(
        NodeSpec::new(
            "write_cameras",
            "Writes a camera path: the book's cameras file (`Frame i`, R rows, t) or JSON (with K \
             when known). The write is atomic.",
        )
        .mode(Mode::Once)
        .param(ParamSpec::required(
            "path",
            ParamType::Path(PathRole::Output),
            "output file",
        ))
        .param(ParamSpec::optional(
            "format",
            ParamType::Enum(&["auto", "book", "json"]),
            ParamValue::Str("auto".into()),
            "auto: JSON for a .json path, else the book's format",
        ))
        .input(PortSpec::one(
            "cameras",
            CameraPathArt::NAME,
            "the path to write",
        )),
        run_write_cameras,
    ));

    r.register_node(FnNode::new(
        NodeSpec::new(
            "plot_solve_error",
            "Plots a solve's report as SVG: reprojection RMS per frame and inliers per frame \
             (what a tracker's solve panel shows).",
        )
        .mode(Mode::Once)
        .param(ParamSpec::required(
            "path",
            ParamType::Path(PathRole::Output),
            "output .svg file",
        ))
        .input(PortSpec::one(
            "report",
            ReportArt::NAME,
            "the report of matchmove, relax or global_bundle_adjust",
        )),
        run_plot,
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, Value};

    use vfxgraph_vision::matchmove::synthetic::{synthetic_shot, ShotOptions};

    fn shot() -> vfxgraph_vision::matchmove::synthetic::SyntheticShot {
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
        s: &vfxgraph_vision::matchmove::synthetic::SyntheticShot,
    ) -> (
        Result<(), NodeError>,
        Option<CameraPathArt>,
        Option<ReportArt>,
    ) {
        let sp = spec("matchmove");
        let p = params(&sp, &[("min_frames", ParamValue::Int(30))]);
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
        let report = report.unwrap().0;
        let rms = report["overall_rms"].as_f64().unwrap();
        assert!(rms < 1.0, "overall RMS {rms}");
        assert_eq!(report["frames"].as_array().unwrap().len(), 70);
        assert!(report["score"]["median"].as_f64().unwrap() < 1.0);
    }

    /// A degenerate input (a tripod pan, no parallax) gives a clear error, never NaN cameras.
    #[test]
    fn a_tripod_pan_is_a_clear_error() {
        let s = synthetic_shot(&ShotOptions {
            frames: 70,
            slots: 80,
            travel: 0.0,
            outlier_fraction: 0.0,
            ..ShotOptions::default()
        });
        let err = run_node(&s).0.unwrap_err().to_string();
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
