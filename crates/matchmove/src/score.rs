//! Scoring a camera path against tracks the way the book's own solution was scored for this
//! project: every maximal run of a feature with status 0 is a track; each is
//! triangulated linearly from all its frames that have a camera and refined by Gauss–Newton with
//! the cameras fixed; the per-observation reprojection errors over ALL tracks (no inlier
//! filtering) are summarized. Also the smoothness of the path: the largest frame-to-frame
//! rotation and the ratio of the largest to the median frame-to-frame camera displacement.

use nalgebra::{Point2, Point3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::formats::cameras::CameraPath;
use vfxgraph_klt::Tracks;

use crate::structure::{p_matrix, poses_by_index, reprojection_error};

/// The figures of [`score_cameras`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BookScore {
    /// Frames of the tracks that have a camera, and frames in all.
    pub frames_with_camera: usize,
    /// Frames of the tracks.
    pub frames: usize,
    /// Tracks scored (seen in ≥ 2 posed frames and triangulable).
    pub tracks_scored: usize,
    /// Observations scored.
    pub observations: usize,
    /// Median reprojection error, pixels.
    pub median: f64,
    /// Mean reprojection error, pixels.
    pub mean: f64,
    /// Fraction of observations above 2 px.
    pub above_2px: f64,
    /// The largest per-frame RMS (over all observations of the frame), pixels, and its frame.
    pub worst_frame_rms: f64,
    /// Frame number of the worst frame.
    pub worst_frame: i64,
    /// Largest rotation between consecutive posed frames, degrees.
    pub max_rotation_step_deg: f64,
    /// Largest over median camera-centre displacement between consecutive posed frames.
    pub translation_step_ratio: f64,
}

/// The distance between the observation and the dehomogenized image of X, whichever side of the
/// camera X is on (what a scorer that knows only P = K[R|t] measures); infinite only on the
/// principal plane.
fn projective_error(k: &Intrinsics, p: &Pose, x: &nalgebra::Vector3<f64>, o: &[f64; 2]) -> f64 {
    let c = p.r * x + p.t;
    if c.z.abs() < 1e-12 {
        return reprojection_error(k, p, x, o);
    }
    let (u, v) = (c.x / c.z, c.y / c.z);
    let q = [k.f1 * u + k.s * v + k.u0, k.f2 * v + k.v0];
    ((q[0] - o[0]).powi(2) + (q[1] - o[1]).powi(2)).sqrt()
}

/// Errors of one track's observations (frame index, error), or `None` if it cannot be scored.
fn track_errors(
    k: &Intrinsics,
    t: &vfxgraph_klt::Track,
    poses: &[Option<Pose>],
) -> Option<Vec<(usize, f64)>> {
    let views: Vec<(usize, &Pose, [f64; 2])> = t
        .points
        .iter()
        .enumerate()
        .filter_map(|(j, o)| {
            poses
                .get(t.first + j)?
                .as_ref()
                .map(|p| (t.first + j, p, *o))
        })
        .collect();
    if views.len() < 2 {
        return None;
    }
    let ps: Vec<_> = views.iter().map(|(_, p, _)| p_matrix(k, p)).collect();
    let xs: Vec<_> = views
        .iter()
        .map(|(_, _, o)| Point2::new(o[0], o[1]))
        .collect();
    let x0 = vfxgraph_geometry::two_view::triangulate_linear_n(&ps, &xs).ok()?;
    let lm = vfxgraph_geometry::optimize::LmOptions {
        max_iterations: 50,
        ..Default::default()
    };
    let x: Point3<f64> =
        vfxgraph_geometry::two_view::triangulate_nonlinear(&ps, &xs, &x0, &lm).unwrap_or(x0);
    Some(
        views
            .iter()
            .map(|(f, p, o)| (*f, projective_error(k, p, &x.coords, o)))
            .collect(),
    )
}

/// Scores `path` (with intrinsics `k`) against `tracks` (module docs).
pub fn score_cameras(tracks: &Tracks, k: &Intrinsics, path: &CameraPath) -> BookScore {
    let poses = poses_by_index(tracks, path);
    score_poses(tracks, k, &poses)
}

/// [`score_cameras`] on poses by frame index.
pub fn score_poses(tracks: &Tracks, k: &Intrinsics, poses: &[Option<Pose>]) -> BookScore {
    let per_track: Vec<Option<Vec<(usize, f64)>>> = tracks
        .tracks
        .par_iter()
        .map(|t| track_errors(k, t, poses))
        .collect();
    let n = tracks.frames.len();
    let mut errors = Vec::new();
    let mut frame_sq = vec![(0.0f64, 0usize); n];
    let mut scored = 0;
    for e in per_track.iter().flatten() {
        scored += 1;
        for &(f, err) in e {
            errors.push(err);
            frame_sq[f].0 += err * err;
            frame_sq[f].1 += 1;
        }
    }
    errors.sort_by(|a, b| a.total_cmp(b));
    let median = if errors.is_empty() {
        f64::NAN
    } else {
        errors[errors.len() / 2]
    };
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    let above = errors.iter().filter(|&&e| e > 2.0).count() as f64 / errors.len().max(1) as f64;
    let (mut worst, mut worst_frame) = (0.0f64, -1i64);
    for (f, (s, c)) in frame_sq.iter().enumerate() {
        if *c > 0 {
            let rms = (s / *c as f64).sqrt();
            if rms > worst || worst_frame < 0 {
                worst = rms;
                worst_frame = tracks.frames[f];
            }
        }
    }
    let posed: Vec<&Pose> = poses.iter().flatten().collect();
    let mut max_rot = 0.0f64;
    let mut steps = Vec::new();
    for w in posed.windows(2) {
        max_rot = max_rot.max(
            vfxgraph_geometry::rotation::rotation_angle_between(&w[0].r, &w[1].r).to_degrees(),
        );
        steps.push((w[1].center() - w[0].center()).norm());
    }
    let max_step = steps.iter().cloned().fold(0.0, f64::max);
    let mut sorted = steps.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let median_step = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
    BookScore {
        frames_with_camera: posed.len(),
        frames: n,
        tracks_scored: scored,
        observations: errors.len(),
        median,
        mean,
        above_2px: above,
        worst_frame_rms: worst,
        worst_frame,
        max_rotation_step_deg: max_rot,
        translation_step_ratio: if median_step > 0.0 {
            max_step / median_step
        } else {
            f64::INFINITY
        },
    }
}
