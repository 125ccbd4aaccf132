//! The book's matchmove with K known ([`matchmove`], chapter 7, stages 1–6 of the crate
//! documentation): fragments solved in parallel, joined, extended to every frame and adjusted
//! as one, into a [`Solve`] of cameras, points and figures.

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::cameras::CameraPath;
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_klt::Tracks;

use crate::fragment::FragmentSolution;
use crate::fragments::split_fragments;
use crate::global::{global_bundle_adjust, GlobalOptions};
use crate::junction::join_fragments;
use crate::options::MatchmoveOptions;
use crate::report::{SolveReport, StageTime};
use crate::structure::{cloud_from_points, derive_seed, inlier_marks, path_from_poses};
use crate::{extend, recovery, report, score};

/// The result of a solve: cameras, points, figures.
#[derive(Clone, Debug)]
pub struct Solve {
    /// One pose per frame (with K attached).
    pub path: CameraPath,
    /// The reconstructed points, with the track id of each.
    pub cloud: PointCloud,
    /// Figures: per frame, per track, per stage.
    pub report: SolveReport,
}

/// Runs the whole matchmove on `tracks` with intrinsics `k` (book chapter 7, stages 1–6 of the
/// module documentation). `progress` is called with (stage, done, total) for long work.
pub fn matchmove(
    tracks: &Tracks,
    k: &Intrinsics,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    k.validate()?;
    tracks
        .validate()
        .map_err(|e| VisionError::InvalidInput(format!("tracks: {e}")))?;
    let n = tracks.frames.len();
    if n < 2 {
        return Err(VisionError::InvalidInput(format!(
            "a matchmove needs at least 2 frames, the tracks have {n}"
        )));
    }
    let mut stages = Vec::new();
    let t0 = Instant::now();
    let fragments = split_fragments(tracks, &options.fragments)?;
    stages.push(StageTime::new("fragments", t0));

    let t0 = Instant::now();
    let done = std::sync::atomic::AtomicUsize::new(0);
    progress("fragments", 0, fragments.len());
    let attempts: Vec<recovery::Attempt> = fragments
        .par_iter()
        .enumerate()
        .map(|(i, frag)| {
            let r = recovery::solve_with_retries(
                tracks,
                k,
                frag,
                options,
                derive_seed(options.seed, 1, i as u64),
                0,
            );
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress("fragments", d, fragments.len());
            r
        })
        .collect();
    let mut notes = Vec::new();
    let mut warnings = Vec::new();
    let mut pieces: Vec<recovery::Piece> = Vec::new();
    for a in attempts {
        notes.extend(a.notes);
        pieces.extend(a.pieces);
    }
    // The longest run of consecutive solved pieces is joined; the frames of pieces that could
    // not be started are registered to its structure by the extension stage.
    let run = recovery::longest_run(&pieces);
    if run.is_empty() {
        return Err(recovery::no_start_error(tracks, &pieces));
    }
    for (i, p) in pieces.iter().enumerate() {
        let frag = match p {
            Err((frag, e)) => Some((frag, e.to_string())),
            Ok(s) if !run.contains(&i) => Some((
                &s.fragment,
                "not joined to the longest solved run of the shot".to_string(),
            )),
            Ok(_) => None,
        };
        if let Some((frag, why)) = frag {
            notes.push(format!(
                "frames {}..{} could not be started on their own ({why}); their cameras were \
                 resected from the structure of their neighbours",
                tracks.frames[frag.first], tracks.frames[frag.last]
            ));
        }
    }
    let solutions: Vec<FragmentSolution> = pieces.drain(run).filter_map(|p| p.ok()).collect();
    for s in &solutions {
        if let Some(a) = &s.report.ambiguity {
            warnings.push(format!(
                "frames {}..{}: a second motion explains the tracks nearly as well ({} of {} \
                 features; its rotation differs by {:.2}° over the pair {}–{}): the cameras may \
                 be wrong by up to that — a plane seen along a straight path does not decide \
                 between them; track features off the plane, or give a longer shot",
                s.report.frames.0,
                s.report.frames.1,
                a.inliers,
                s.report.inliers.max(s.report.pair_inliers),
                a.rotation_deg,
                s.report.pair.0,
                s.report.pair.1
            ));
        }
    }
    stages.push(StageTime::new("fragment calibration", t0));

    let t0 = Instant::now();
    let joined = join_fragments(tracks, k, &solutions, &options.scale)?;
    stages.push(StageTime::new("scale and junction", t0));

    let t0 = Instant::now();
    let (mut poses, mut points) = extend::extend_to_all_frames(
        tracks,
        k,
        joined.poses,
        joined.points,
        derive_seed(options.seed, 2, 0),
    )?;
    stages.push(StageTime::new("extension", t0));

    if let Some(g) = &options.global {
        let t0 = Instant::now();
        progress("global bundle adjustment", 0, 1);
        let adjusted = global_bundle_adjust(tracks, k, &poses, g)?;
        poses = adjusted.0;
        points = adjusted.1;
        progress("global bundle adjustment", 1, 1);
        stages.push(StageTime::new("global bundle adjustment", t0));
    }

    // The inlier threshold of the stage that made the final cameras and points.
    let tolerance = options.global.as_ref().map_or(
        options.refine.final_tolerance(),
        GlobalOptions::final_threshold,
    );
    let mut solve = finish_solve(tracks, k, &poses, &points, tolerance, stages, options.score)?;
    solve.report.notes = notes;
    solve.report.warnings = warnings;
    solve.report.fragments = solutions
        .iter()
        .zip(&joined.scales)
        .map(|(s, &scale)| {
            let mut r = s.report.clone();
            r.scale = scale;
            r
        })
        .collect();
    Ok(solve)
}

/// Builds the [`Solve`] of poses and points: the path (with K), the cloud, and the report with
/// the given stage times and, when `with_score` is set, the book-style score of [`score`].
/// The solve's final inlier decision ([`inlier_marks`] at `inlier_tolerance`) is the one the
/// report counts and the cloud carries (`PointCloud::inlier_frames`).
pub fn finish_solve(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    inlier_tolerance: f64,
    stages: Vec<StageTime>,
    with_score: bool,
) -> Result<Solve> {
    let path = path_from_poses(tracks, k, poses)?;
    let marks = inlier_marks(tracks, k, poses, points, inlier_tolerance);
    let cloud = cloud_from_points(tracks, k, poses, points, &marks);
    let t0 = Instant::now();
    let mut report = report::solve_report(tracks, k, poses, points, &marks, inlier_tolerance);
    report.stages = stages;
    report
        .stages
        .push(StageTime::new("report and per-frame confidence", t0));
    if with_score {
        let t0 = Instant::now();
        report.score = Some(score::score_poses(tracks, k, poses));
        report.stages.push(StageTime::new("scoring", t0));
    }
    Ok(Solve {
        path,
        cloud,
        report,
    })
}

/// The fraction done of a [`matchmove`] that reached `done` of `total` in `stage` (its
/// progress callback's arguments): the fragments are most of the work (70 %), the global
/// adjustment the rest.
pub fn solve_progress(stage: &str, done: usize, total: usize) -> f32 {
    let part = done as f32 / total.max(1) as f32;
    if stage == "fragments" {
        0.7 * part
    } else {
        0.7 + 0.3 * part
    }
}
