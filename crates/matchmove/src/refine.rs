//! A solved path refined again, each as a [`Solve`]: the book's relaxation (§7.14,
//! [`relax_path`]) and the robust global bundle adjustment ([`adjust_path`]), the `relax` and
//! `global_bundle_adjust` nodes.

use std::time::Instant;

use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::cameras::CameraPath;
use vfxgraph_klt::Tracks;
use vfxgraph_params::Options;

use crate::global::{global_bundle_adjust, GlobalOptions};
use crate::lens::undistort_tracks;
use crate::pipeline::{finish_solve, Solve};
use crate::relax::{relax, RelaxOptions};
use crate::report::StageTime;
use crate::structure::poses_by_index;

/// Whether a solve that refines a path scores its cameras (the `relax` and
/// `global_bundle_adjust` nodes; [`crate::options::MatchmoveOptions::score`] is `matchmove`'s).
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
/// with the cameras (held: the lens is solved by [`crate::solve::matchmove_with_lens`]).
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
