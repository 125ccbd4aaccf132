//! vfxgraph-matchmove: the camera of every frame of a shot, from feature tracks and known
//! intrinsics K, after chapter 7 of *Introduction to Visual Effects: A Computational Approach*
//! (Madeira & Velho, 2023).
//!
//! The stages, each its own module, named as the book's chapter 7 names them:
//!
//! 1. [`fragments`] (§7.11) cuts the sequence into overlapping fragments;
//! 2. [`pair`] (§7.2–7.6) finds each fragment's best frame pair: by default from the calibrated
//!    minimal solvers (five-point E or the homography's motions, P3P for every frame), with
//!    `init: book` the book's RANSAC on F, E, cheirality, triangulation, DLT resection of every
//!    frame and the intrinsics-consistency test;
//! 3. [`fragment`] (§7.9) resects every frame of a fragment and runs the refinement cycles
//!    (bundle adjustment, re-triangulation at 10, 5, 3 px); [`recovery`] retries a fragment
//!    that cannot start and keeps the longest run of solved pieces;
//! 4. [`junction`] (§7.12) finds the scale between neighbouring fragments and chains them into
//!    the first fragment's frame and scale;
//! 5. [`extend`] gives a camera to frames no fragment covers (resection from the joined cloud);
//! 6. [`global`] bundle-adjusts the whole sequence with a robust loss, and [`relax`] (§7.14) is
//!    the book's alternating relaxation;
//! 7. [`score`] measures a solve the way the book's own cameras were scored, and [`report`]
//!    gathers per-frame and per-track figures and the warnings; [`corpus`] generates the
//!    robustness corpus the solve is measured on.
//!
//! [`matchmove`] runs stages 1–6 (fragments in parallel); every constant is in
//! [`MatchmoveOptions`] with the book's value as default.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod adjust;
pub mod corpus;
pub mod extend;
pub mod fragment;
pub mod fragments;
pub mod global;
pub mod junction;
pub mod lens_solve;
pub mod pair;
pub mod recovery;
pub mod relax;
pub mod report;
pub mod score;
pub mod synthetic;
pub mod track_weights;
pub mod tripod;
pub mod zoom;

use std::time::Instant;

use nalgebra::{Matrix3x4, Point2, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use vfxgraph_params::Options;

use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::cameras::{CameraPath, FramePose};
use vfxgraph_klt::Tracks;
use vfxgraph_geometry::points::PointCloud;

pub(crate) use adjust::{
    adjust_with_block, adjust_with_blocks, bundle_adjust_indexed, bundle_adjust_lens,
    intrinsics_of_block, lens_block, solved_intrinsics, BlockCovariance, Held,
};
pub use fragment::{solve_fragment, Ambiguity, FragmentSolution, RefineOptions};
pub use fragments::{split_fragments, Fragment, FragmentOptions};
pub use global::{global_bundle_adjust, GlobalOptions};
pub use junction::{join_fragments, ScaleOptions};
pub use lens_solve::{
    estimate_focal, matchmove_with_lens, undistort_tracks, DistortionMode, FocalMode, LensOptions,
    PrincipalPoint,
};
pub use pair::{InitMethod, PairOptions, PairRejections};
pub use relax::{relax, RelaxOptions};
pub use report::{SolveReport, StageTime};
pub use score::{score_cameras, BookScore};
pub use tripod::{measure_parallax, solve_rotations, MotionOptions, Parallax, SolveMode};

/// Poses by frame index (`None`: no camera for that frame).
pub type Poses = Vec<Option<Pose>>;
/// Points by track index (`None`: no point for that track).
pub type TrackPoints = Vec<Option<Vector3<f64>>>;
/// A camera path and its structure, by frame and track index.
pub type Structure = (Poses, TrackPoints);

/// Every constant of the matchmove, with the book's values as defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, vfxgraph_params::Options)]
#[serde(default)]
pub struct MatchmoveOptions {
    /// Fragment cutting (§7.11).
    #[param(flatten)]
    pub fragments: FragmentOptions,
    /// Best-pair search (§7.2–7.6).
    #[param(flatten)]
    pub pair: PairOptions,
    /// Refinement cycles (§7.9).
    #[param(flatten)]
    pub refine: RefineOptions,
    /// Scale search between fragments (§7.12).
    #[param(flatten)]
    pub scale: ScaleOptions,
    /// finish with a robust bundle adjustment of the whole sequence
    ///
    /// Not in the book; `None` skips it.
    #[param(toggle = "global_adjust")]
    pub global: Option<GlobalOptions>,
    /// The lens: what of the focal length and distortion is solved ([`matchmove_with_lens`];
    /// [`matchmove`] itself ignores it and takes K as exact and the tracks as a pinhole's).
    #[param(flatten)]
    pub lens: LensOptions,
    /// The camera's motion: general, or a nodal pan ([`tripod`]), or detected.
    #[param(flatten)]
    pub motion: tripod::MotionOptions,
    /// Seed of every random choice (RANSAC samples); each fragment derives its own stream.
    #[param(skip)]
    pub seed: u64,
    /// score the cameras against every track into the report
    ///
    /// The book-style score of [`score`].
    pub score: bool,
}

impl Default for MatchmoveOptions {
    fn default() -> Self {
        MatchmoveOptions {
            fragments: FragmentOptions::default(),
            pair: PairOptions::default(),
            refine: RefineOptions::default(),
            scale: ScaleOptions::default(),
            global: Some(GlobalOptions::default()),
            lens: LensOptions::default(),
            motion: tripod::MotionOptions::default(),
            seed: 0,
            score: true,
        }
    }
}

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

/// Projects X with K and pose; `None` behind the camera.
#[inline]
pub(crate) fn project(k: &Intrinsics, pose: &Pose, x: &Vector3<f64>) -> Option<[f64; 2]> {
    let c = pose.r * x + pose.t;
    if c.z <= 1e-12 {
        return None;
    }
    let (u, v) = (c.x / c.z, c.y / c.z);
    Some([k.f1 * u + k.s * v + k.u0, k.f2 * v + k.v0])
}

/// X's pixel under K and pose, and the Jacobian of that pixel with respect to the pose as a
/// left rotation increment δω (R ← exp([δω]ₓ)R) and a translation increment δt:
/// ∂pixel/∂c · [−[RX]ₓ | I] with c = RX + t. `None` behind the camera.
#[inline]
pub(crate) fn pose_jacobian(
    k: &Intrinsics,
    pose: &Pose,
    x: &Vector3<f64>,
) -> Option<([f64; 2], nalgebra::Matrix2x6<f64>)> {
    let rx = pose.r * x;
    let c = rx + pose.t;
    if c.z <= 1e-12 {
        return None;
    }
    let iz = 1.0 / c.z;
    let (u, v) = (c.x * iz, c.y * iz);
    let pixel = [k.f1 * u + k.s * v + k.u0, k.f2 * v + k.v0];
    // d(pixel)/d(c).
    let jc = nalgebra::Matrix2x3::new(
        k.f1 * iz,
        k.s * iz,
        -(k.f1 * u + k.s * v) * iz,
        0.0,
        k.f2 * iz,
        -k.f2 * v * iz,
    );
    let jw = jc * (-vfxgraph_geometry::rotation::skew(&rx));
    let mut j = nalgebra::Matrix2x6::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&jw);
    j.fixed_view_mut::<2, 3>(0, 3).copy_from(&jc);
    Some((pixel, j))
}

/// Reprojection error of X seen at `obs`, infinity behind the camera.
#[inline]
pub(crate) fn reprojection_error(
    k: &Intrinsics,
    pose: &Pose,
    x: &Vector3<f64>,
    obs: &[f64; 2],
) -> f64 {
    match project(k, pose, x) {
        Some(p) => ((p[0] - obs[0]).powi(2) + (p[1] - obs[1]).powi(2)).sqrt(),
        None => f64::INFINITY,
    }
}

/// P = K[R|t].
pub(crate) fn p_matrix(k: &Intrinsics, pose: &Pose) -> Matrix3x4<f64> {
    k.k() * pose.matrix3x4()
}

/// Triangulates a point from its observations in posed frames (linear, then Gauss–Newton on the
/// reprojection error); `None` if it lands at infinity or behind a camera.
pub(crate) fn triangulate_views(
    k: &Intrinsics,
    views: &[(&Pose, [f64; 2])],
) -> Option<Vector3<f64>> {
    if views.len() < 2 {
        return None;
    }
    let ps: Vec<Matrix3x4<f64>> = views.iter().map(|(p, _)| p_matrix(k, p)).collect();
    let xs: Vec<Point2<f64>> = views.iter().map(|(_, x)| Point2::new(x[0], x[1])).collect();
    let x0 = vfxgraph_geometry::two_view::triangulate_linear_n(&ps, &xs).ok()?;
    let lm = vfxgraph_geometry::optimize::LmOptions {
        max_iterations: 10,
        ..Default::default()
    };
    let x = vfxgraph_geometry::two_view::triangulate_nonlinear(&ps, &xs, &x0, &lm).unwrap_or(x0);
    let v = x.coords;
    if !v.iter().all(|c| c.is_finite()) {
        return None;
    }
    if views.iter().any(|(p, _)| (p.r * v + p.t).z <= 0.0) {
        return None;
    }
    Some(v)
}

/// Observations of one track in frame indices `range` (all of them, in order), or `None` if the
/// track is not seen in every frame of the range.
pub(crate) fn through(track: &vfxgraph_klt::Track, first: usize, last: usize) -> Option<&[[f64; 2]]> {
    if track.first <= first && track.end() > last {
        Some(&track.points[first - track.first..=last - track.first])
    } else {
        None
    }
}

/// A per-purpose seed: the options' seed mixed with a stage tag and an index (splitmix64), so that
/// parallel stages draw independent, reproducible streams.
pub(crate) fn derive_seed(seed: u64, tag: u64, index: u64) -> u64 {
    let mut z =
        seed ^ tag.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
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

/// Whether a solve that refines a path scores its cameras (the `relax` and
/// `global_bundle_adjust` nodes; [`MatchmoveOptions::score`] is `matchmove`'s).
#[derive(Debug, PartialEq, Options)]
pub struct Score {
    /// score the cameras against every track into the report
    pub score: bool,
}

impl Default for Score {
    fn default() -> Self {
        Score { score: true }
    }
}

/// The params of [`adjust_path`] (the `global_bundle_adjust` node).
#[derive(Debug, Default, PartialEq, Options)]
pub struct GlobalPathOptions {
    /// Scoring.
    #[param(flatten)]
    pub score: Score,
    /// The adjustment.
    #[param(flatten)]
    pub global: GlobalOptions,
}

/// The params of [`relax_path`] (the `relax` node).
#[derive(Debug, Default, PartialEq, Options)]
pub struct RelaxPathOptions {
    /// The relaxation.
    #[param(flatten)]
    pub relax: RelaxOptions,
    /// Scoring.
    #[param(flatten)]
    pub score: Score,
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

/// The book's relaxation (§7.14, [`relax()`]) of a solved path, as a [`Solve`]. A lens on `k`
/// is undistorted from the tracks first ([`pinhole_view`]) and returned with the cameras.
pub fn relax_path(
    tracks: &Tracks,
    k: &Intrinsics,
    path: &CameraPath,
    options: &RelaxOptions,
    with_score: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Solve> {
    let (tracks, kp) = pinhole_view(tracks, k)?;
    let poses = require_all_frames(&tracks, path)?;
    let t0 = Instant::now();
    let (poses, points) = relax(&tracks, &kp, &poses, options, progress)?;
    let stages = vec![StageTime::new("relaxation", t0)];
    let tol = (options.initial_tolerance - options.tolerance_step * options.rounds as f64)
        .max(options.tolerance_step.max(0.5));
    let mut solve = finish_solve(&tracks, &kp, &poses, &points, tol, stages, with_score)?;
    solve.path.intrinsics = Some(k.clone());
    Ok(solve)
}

/// A robust global bundle adjustment ([`global_bundle_adjust`]) of a solved path, as a
/// [`Solve`]. A lens on `k` is undistorted from the tracks first ([`pinhole_view`]) and returned
/// with the cameras (held: the lens is solved by [`matchmove_with_lens`]).
pub fn adjust_path(
    tracks: &Tracks,
    k: &Intrinsics,
    path: &CameraPath,
    options: &GlobalOptions,
    with_score: bool,
) -> Result<Solve> {
    let (tracks, kp) = pinhole_view(tracks, k)?;
    let poses = require_all_frames(&tracks, path)?;
    let t0 = Instant::now();
    let (poses, points) = global_bundle_adjust(&tracks, &kp, &poses, options)?;
    let stages = vec![StageTime::new("global bundle adjustment", t0)];
    let tol = options.final_threshold();
    let mut solve = finish_solve(&tracks, &kp, &poses, &points, tol, stages, with_score)?;
    solve.path.intrinsics = Some(k.clone());
    Ok(solve)
}

/// The tracks as the ideal pinhole of `k` sees them, with that pinhole: `tracks` and `k`
/// themselves (no copy) when `k` has no lens, else the tracks undistorted
/// ([`undistort_tracks`]) and `k` without its lens.
pub fn pinhole_view<'a>(
    tracks: &'a Tracks,
    k: &Intrinsics,
) -> Result<(std::borrow::Cow<'a, Tracks>, Intrinsics)> {
    if k.is_pinhole() {
        Ok((std::borrow::Cow::Borrowed(tracks), k.clone()))
    } else {
        Ok((
            std::borrow::Cow::Owned(undistort_tracks(tracks, k)?),
            k.pinhole(),
        ))
    }
}

/// The path's poses by frame index of `tracks`; every frame of the tracks must have one.
fn require_all_frames(tracks: &Tracks, path: &CameraPath) -> Result<Vec<Option<Pose>>> {
    let poses = poses_by_index(tracks, path);
    let missing: Vec<i64> = poses
        .iter()
        .zip(&tracks.frames)
        .filter(|(p, _)| p.is_none())
        .map(|(_, f)| *f)
        .collect();
    if !missing.is_empty() {
        return Err(VisionError::InvalidInput(format!(
            "the camera path has no camera for {} frames of the tracks (first: {})",
            missing.len(),
            missing[0]
        )));
    }
    Ok(poses)
}

/// A camera path from per-frame-index poses; every frame must have one.
pub(crate) fn path_from_poses(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
) -> Result<CameraPath> {
    let mut frames = Vec::with_capacity(poses.len());
    for (i, p) in poses.iter().enumerate() {
        let Some(p) = p else {
            return Err(VisionError::Degenerate(format!(
                "frame {} has no camera",
                tracks.frames[i]
            )));
        };
        if !(p.r.iter().chain(p.t.iter()).all(|v| v.is_finite())) {
            return Err(VisionError::Degenerate(format!(
                "frame {}: the solved camera is not finite",
                tracks.frames[i]
            )));
        }
        let frame = usize::try_from(tracks.frames[i]).map_err(|_| {
            VisionError::InvalidInput(format!("negative frame number {}", tracks.frames[i]))
        })?;
        frames.push(FramePose {
            frame,
            pose: p.clone(),
            focal: None,
        });
    }
    Ok(CameraPath {
        frames,
        intrinsics: Some(k.clone()),
    })
}

/// Poses of a camera path by frame index of `tracks` (`None` where the path has no camera).
pub fn poses_by_index(tracks: &Tracks, path: &CameraPath) -> Vec<Option<Pose>> {
    let by_frame: std::collections::HashMap<i64, &Pose> = path
        .frames
        .iter()
        .map(|f| (f.frame as i64, &f.pose))
        .collect();
    tracks
        .frames
        .iter()
        .map(|f| by_frame.get(f).map(|p| (*p).clone()))
        .collect()
}

/// The solve's final decision on every observation, by track index and observation: an inlier
/// when its frame has a camera, its track a point, and its reprojection error is at most
/// `tolerance` px in the final cameras and points. This is the rule every outlier-marking
/// stage applies (the relaxation's re-marking of §7.14, the global adjustment's rounds, the
/// refinement cycles of §7.9), applied once more to the result at the stage's last tolerance.
pub(crate) fn inlier_marks(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    tolerance: f64,
) -> Vec<Vec<bool>> {
    tracks
        .tracks
        .iter()
        .zip(points)
        .map(|(t, x)| {
            t.points
                .iter()
                .enumerate()
                .map(|(j, obs)| match (x, poses.get(t.first + j)) {
                    (Some(x), Some(Some(p))) => reprojection_error(k, p, x, obs) <= tolerance,
                    _ => false,
                })
                .collect()
        })
        .collect()
}

/// A point cloud from points keyed by track index, with each point's RMS error over its inlier
/// observations (`marks`, from [`inlier_marks`]) and the frames of those observations.
pub(crate) fn cloud_from_points(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    marks: &[Vec<bool>],
) -> PointCloud {
    let mut cloud = PointCloud::default();
    for ((t, x), m) in tracks.tracks.iter().zip(points).zip(marks) {
        let Some(x) = x else { continue };
        let (mut s, mut frames) = (0.0, Vec::new());
        for (j, obs) in t.points.iter().enumerate() {
            if let (true, Some(Some(p))) = (m[j], poses.get(t.first + j)) {
                s += reprojection_error(k, p, x, obs).powi(2);
                frames.push(tracks.frames[t.first + j]);
            }
        }
        cloud.points.push([x.x, x.y, x.z]);
        cloud.track_ids.push(t.id);
        cloud.errors.push(if frames.is_empty() {
            f64::NAN
        } else {
            (s / frames.len() as f64).sqrt()
        });
        cloud.inlier_frames.push(frames);
    }
    cloud
}

/// Points keyed by track index from a cloud (tracks without a point get `None`).
pub fn points_by_track(tracks: &Tracks, cloud: &PointCloud) -> Vec<Option<Vector3<f64>>> {
    let by_id: std::collections::HashMap<u64, [f64; 3]> = cloud
        .track_ids
        .iter()
        .copied()
        .zip(cloud.points.iter().copied())
        .collect();
    tracks
        .tracks
        .iter()
        .map(|t| by_id.get(&t.id).map(|p| Vector3::new(p[0], p[1], p[2])))
        .collect()
}

#[cfg(test)]
mod tests;
