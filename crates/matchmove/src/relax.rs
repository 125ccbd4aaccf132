//! Relaxation (book §7.14): a global refinement of a joined camera path
//! by alternating point and camera optimizations.
//!
//! Every track longer than `min_run` frames becomes a *homologous point*; it is triangulated from
//! the pair of frames whose two-view triangulation has the most frames with error below
//! `agree_tolerance`, and kept if more than `min_run` frames agree. Then `rounds` rounds; each runs
//! `cycles` cycles of (optimize every point with the cameras fixed, then every camera — its 6
//! pose parameters — with the points fixed, each by Levenberg–Marquardt over its inlier
//! observations) and ends by re-marking the inliers with a tolerance that starts at
//! `initial_tolerance` and drops by `tolerance_step` per round.
//!
//! Points and cameras are independent within a step, so each step runs in parallel; the result
//! does not depend on the thread count. The book tries every frame pair per point; we try every
//! `pair_stride`-th frame.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::rotation::axis_angle_to_r;
use vfxgraph_klt::Tracks;
use vfxgraph_params::Options;

use crate::structure::{reprojection_error, triangulate_views};

/// The relaxation's constants (book values as defaults).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
pub struct RelaxOptions {
    /// tracks longer than this become homologous points
    ///
    /// Book: 45 frames.
    #[param(range = 2..=100_000)]
    pub min_run: usize,
    /// a frame agrees with a point's triangulation below this error, px
    ///
    /// Book: 10.
    #[param(range = 1e-3..=1e4)]
    pub agree_tolerance: f64,
    /// rounds
    ///
    /// Book: 9.
    #[param(range = 0..=1000)]
    pub rounds: usize,
    /// point/camera cycles per round
    ///
    /// Book: 10.
    #[param(range = 1..=1000)]
    pub cycles: usize,
    /// inlier tolerance of the first round, px
    ///
    /// Book: 10.
    #[param(range = 1e-3..=1e4)]
    pub initial_tolerance: f64,
    /// its decrease per round, px
    ///
    /// Book: 1.
    #[param(range = 0.0..=1e4)]
    pub tolerance_step: f64,
    /// LM iterations per point or camera optimization
    #[param(range = 1..=1000)]
    pub lm_iterations: usize,
    /// pair search over every n-th frame of a track
    ///
    /// The candidate frames of the pair search (book: 1).
    #[param(range = 1..=10_000)]
    pub pair_stride: usize,
}

impl Default for RelaxOptions {
    fn default() -> Self {
        RelaxOptions {
            min_run: 45,
            agree_tolerance: 10.0,
            rounds: 9,
            cycles: 10,
            initial_tolerance: 10.0,
            tolerance_step: 1.0,
            lm_iterations: 3,
            pair_stride: 4,
        }
    }
}

/// Triangulates a homologous point from its best frame pair (module docs).
fn homologous_point(
    k: &Intrinsics,
    track: &vfxgraph_klt::Track,
    poses: &[Option<Pose>],
    options: &RelaxOptions,
) -> Option<Vector3<f64>> {
    let posed: Vec<(&Pose, [f64; 2])> = track
        .points
        .iter()
        .enumerate()
        .filter_map(|(j, o)| poses.get(track.first + j)?.as_ref().map(|p| (p, *o)))
        .collect();
    if posed.len() <= options.min_run {
        return None;
    }
    let stride = options.pair_stride.max(1);
    let idx: Vec<usize> = (0..posed.len())
        .step_by(stride)
        .chain([posed.len() - 1])
        .collect();
    let mut best: Option<(usize, Vector3<f64>)> = None;
    for (a, &i) in idx.iter().enumerate() {
        for &j in &idx[a + 1..] {
            if i == j {
                continue;
            }
            let Some(x) = triangulate_views(k, &[posed[i], posed[j]]) else {
                continue;
            };
            let agree = posed
                .iter()
                .filter(|(p, o)| reprojection_error(k, p, &x, o) < options.agree_tolerance)
                .count();
            if best.as_ref().is_none_or(|b| agree > b.0) {
                best = Some((agree, x));
            }
        }
    }
    best.filter(|b| b.0 > options.min_run).map(|b| b.1)
}

/// Gauss–Newton/LM refinement of one point with the cameras fixed.
fn refine_point(
    k: &Intrinsics,
    x: Vector3<f64>,
    views: &[(&Pose, [f64; 2])],
    iters: usize,
) -> Vector3<f64> {
    let ps: Vec<_> = views
        .iter()
        .map(|(p, _)| crate::structure::p_matrix(k, p))
        .collect();
    let xs: Vec<_> = views
        .iter()
        .map(|(_, o)| nalgebra::Point2::new(o[0], o[1]))
        .collect();
    let lm = vfxgraph_geometry::optimize::LmOptions {
        max_iterations: iters,
        ..Default::default()
    };
    vfxgraph_geometry::two_view::triangulate_nonlinear(&ps, &xs, &nalgebra::Point3::from(x), &lm)
        .map(|p| p.coords)
        .unwrap_or(x)
}

/// Cost and normal equations of a camera over its observations.
fn camera_normal_equations(
    k: &Intrinsics,
    pose: &Pose,
    obs: &[(Vector3<f64>, [f64; 2])],
) -> (f64, Matrix6<f64>, Vector6<f64>) {
    let (mut cost, mut h, mut g) = (0.0, Matrix6::zeros(), Vector6::zeros());
    for (x, o) in obs {
        let Some((p, j)) = crate::structure::pose_jacobian(k, pose, x) else {
            continue;
        };
        let r = [p[0] - o[0], p[1] - o[1]];
        cost += r[0] * r[0] + r[1] * r[1];
        let rv = nalgebra::Vector2::new(r[0], r[1]);
        h += j.transpose() * j;
        g += j.transpose() * rv;
    }
    (cost, h, g)
}

/// Levenberg–Marquardt on one camera's 6 pose parameters with the points fixed.
fn refine_camera_pose(
    k: &Intrinsics,
    pose: &Pose,
    obs: &[(Vector3<f64>, [f64; 2])],
    iters: usize,
) -> Pose {
    if obs.len() < 3 {
        return pose.clone();
    }
    let mut pose = pose.clone();
    let mut lambda = 1e-3;
    let (mut cost, mut h, mut g) = camera_normal_equations(k, &pose, obs);
    for _ in 0..iters {
        let mut a = h;
        for d in 0..6 {
            a[(d, d)] *= 1.0 + lambda;
        }
        let Some(step) = a.cholesky().map(|c| c.solve(&(-g))) else {
            lambda *= 10.0;
            continue;
        };
        let dw = Vector3::new(step[0], step[1], step[2]);
        let dt = Vector3::new(step[3], step[4], step[5]);
        let r: Matrix3<f64> = axis_angle_to_r(&dw) * pose.r;
        let cand = Pose::new(r, pose.t + dt);
        let (c2, h2, g2) = camera_normal_equations(k, &cand, obs);
        if c2 < cost {
            pose = cand;
            cost = c2;
            h = h2;
            g = g2;
            lambda = (lambda * 0.1).max(1e-9);
        } else {
            lambda *= 10.0;
        }
    }
    pose
}

/// Relaxes a camera path (module docs). Every frame must be posed; returns the poses and the
/// homologous points by track index.
pub fn relax(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    options: &RelaxOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<crate::structure::Structure> {
    if !(options.initial_tolerance > 0.0) || options.tolerance_step < 0.0 {
        return Err(VisionError::InvalidInput(
            "relaxation tolerances must be positive".into(),
        ));
    }
    let n = tracks.frames.len();
    let mut poses = poses.to_vec();
    let mut points: Vec<Option<Vector3<f64>>> = tracks
        .tracks
        .par_iter()
        .map(|t| homologous_point(k, t, &poses, options))
        .collect();
    let count = points.iter().filter(|p| p.is_some()).count();
    if count < 6 {
        return Err(VisionError::Degenerate(format!(
            "relaxation: only {count} tracks longer than {} frames could be triangulated \
             (lower min_run?)",
            options.min_run
        )));
    }
    // Observations of each frame by track: (track index, observation).
    let mut by_frame: Vec<Vec<(usize, [f64; 2])>> = vec![Vec::new(); n];
    for (ti, t) in tracks.tracks.iter().enumerate() {
        if points[ti].is_some() {
            for (j, o) in t.points.iter().enumerate() {
                by_frame[t.first + j].push((ti, *o));
            }
        }
    }
    let mark =
        |poses: &[Option<Pose>], points: &[Option<Vector3<f64>>], tol: f64| -> Vec<Vec<bool>> {
            tracks
                .tracks
                .par_iter()
                .enumerate()
                .map(|(ti, t)| match &points[ti] {
                    Some(x) => t
                        .points
                        .iter()
                        .enumerate()
                        .map(|(j, o)| {
                            poses[t.first + j]
                                .as_ref()
                                .is_some_and(|p| reprojection_error(k, p, x, o) <= tol)
                        })
                        .collect(),
                    None => vec![false; t.points.len()],
                })
                .collect()
        };
    let mut inlier = mark(&poses, &points, options.initial_tolerance);
    for round in 0..options.rounds {
        progress(round, options.rounds);
        for _ in 0..options.cycles {
            points = tracks
                .tracks
                .par_iter()
                .enumerate()
                .map(|(ti, t)| {
                    let x = points[ti]?;
                    let views: Vec<(&Pose, [f64; 2])> = t
                        .points
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| inlier[ti][*j])
                        .filter_map(|(j, o)| poses[t.first + j].as_ref().map(|p| (p, *o)))
                        .collect();
                    if views.len() < 2 {
                        return Some(x);
                    }
                    Some(refine_point(k, x, &views, options.lm_iterations))
                })
                .collect();
            poses = (0..n)
                .into_par_iter()
                .map(|f| {
                    let p = poses[f].as_ref()?;
                    let obs: Vec<(Vector3<f64>, [f64; 2])> = by_frame[f]
                        .iter()
                        .filter(|(ti, _)| inlier[*ti][f - tracks.tracks[*ti].first])
                        .filter_map(|(ti, o)| points[*ti].map(|x| (x, *o)))
                        .collect();
                    Some(refine_camera_pose(k, p, &obs, options.lm_iterations))
                })
                .collect();
        }
        let tol = (options.initial_tolerance - options.tolerance_step * (round + 1) as f64)
            .max(options.tolerance_step.max(0.5));
        inlier = mark(&poses, &points, tol);
    }
    progress(options.rounds, options.rounds);
    Ok((poses, points))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic camera Jacobian drives LM back to a known pose from a perturbed one.
    #[test]
    fn camera_refinement_recovers_a_known_pose() {
        let k = Intrinsics::new(900.0, 900.0, 640.0, 360.0);
        let truth = Pose::new(
            axis_angle_to_r(&Vector3::new(0.1, -0.2, 0.05)),
            Vector3::new(0.2, -0.1, 4.0),
        );
        let pts: Vec<Vector3<f64>> = (0..30)
            .map(|i| {
                let a = i as f64;
                Vector3::new(
                    (a * 0.37).sin() * 2.0,
                    (a * 0.91).cos() * 1.5,
                    (a * 0.13).sin(),
                )
            })
            .collect();
        let obs: Vec<(Vector3<f64>, [f64; 2])> = pts
            .iter()
            .map(|x| (*x, crate::structure::project(&k, &truth, x).unwrap()))
            .collect();
        let start = Pose::new(
            axis_angle_to_r(&Vector3::new(0.01, 0.02, -0.01)) * truth.r,
            truth.t + Vector3::new(0.05, -0.03, 0.1),
        );
        let got = refine_camera_pose(&k, &start, &obs, 20);
        assert!(vfxgraph_geometry::rotation::rotation_angle_between(&got.r, &truth.r) < 1e-8);
        assert!((got.t - truth.t).norm() < 1e-7, "{:?}", got.t - truth.t);
    }
}
