//! Nodal pans: a camera that only turns about its optical centre (a tripod pan, or a hand-held
//! pan with no usable parallax). An addition to the book, whose fragments need parallax: a
//! pan's tracks do not define the fundamental matrix of §7.2–7.5 (every F = [e]ₓH of the pan's
//! homography H fits them), so the book's pipeline fails or invents a translation.
//!
//! **Solve** ([`solve_rotations`]): the rotations are chained frame by frame (each frame's
//! rotation from the directions of the tracks already seen, RANSAC + Kabsch), then refined by
//! the bundle adjustment with every camera centre held at the origin
//! ([`vfxgraph_bundle::Gauge::RotationOnly`]) and each point a direction (on the unit sphere),
//! in rounds of outlier marking as [`crate::global`] does. An unknown focal length comes from a
//! one-dimensional search of the chained rotations' residual over focal lengths
//! ([`crate::rotations::estimate_rotation_focal`]; a rotating camera's homographies K R K⁻¹
//! fix K: Hartley 1997, "Self-calibration of stationary cameras"), then the adjustment refines
//! it with the lens.
//!
//! Whether a shot is a pan is [`crate::parallax`]'s to measure.

use nalgebra::Vector3;
use vfxgraph_bundle::Gauge;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;

use crate::lens::undistort_tracks;
use crate::options::MatchmoveOptions;
use crate::parallax::Parallax;
use crate::pipeline::Solve;
use crate::report::StageTime;
use crate::rotations::{chain, direction, ROTATION_THRESHOLD};
use crate::structure::{derive_seed, reprojection_error};

/// Solves a nodal pan (module docs): `tracks` as observed, `k` the starting intrinsics with the
/// lens model to refine (`held`: the flags of the block `[f, k1, k2]`), `parallax` what the
/// detection measured (reported). Every camera centre of the returned path is the origin; the
/// cloud's points are the tracks' directions on the unit sphere.
pub fn solve_rotations(
    tracks: &Tracks,
    k: &Intrinsics,
    held: crate::adjust::Held,
    options: &MatchmoveOptions,
    parallax: Option<&Parallax>,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    let t0 = std::time::Instant::now();
    let mut stages = Vec::new();
    let mut k = k.clone();
    let mut und = undistort_tracks(tracks, &k)?;
    progress("rotations", 0, 1);
    let c = chain(&und, &k.pinhole(), derive_seed(options.seed, 13, 0))?;
    let mut rotations = c.rotations;
    let mut points = c.directions;
    let mut flags = c.inliers;
    stages.push(StageTime::new("rotation chain", t0));
    let mut tolerance = ROTATION_THRESHOLD;
    let mut cov = None;
    if let Some(g) = &options.global {
        let t0 = std::time::Instant::now();
        let mut thresholds = vec![g.triangulation_tolerance];
        thresholds.extend(g.thresholds.iter().copied());
        for (round, &threshold) in thresholds.iter().enumerate() {
            progress("rotation adjustment", round, thresholds.len());
            let kp = k.pinhole();
            let mut poses: Vec<Option<Pose>> = rotations
                .iter()
                .map(|r| Some(Pose::new(*r, Vector3::zeros())))
                .collect();
            if round > 0 {
                for (ti, t) in und.tracks.iter().enumerate() {
                    let Some(x) = points[ti] else { continue };
                    let keep: Vec<bool> = t
                        .points
                        .iter()
                        .enumerate()
                        .map(|(j, p)| {
                            let pose = poses[t.first + j].as_ref().expect("every frame posed");
                            reprojection_error(&kp, pose, &x, p) <= threshold
                        })
                        .collect();
                    points[ti] = direction(&kp, t, &rotations, &keep);
                    flags[ti] = keep;
                }
            }
            let keep =
                |ti: usize, f: usize| f64::from(u8::from(flags[ti][f - tracks.tracks[ti].first]));
            let block = crate::adjust::lens_block(&k, held);
            let last = round + 1 == thresholds.len();
            let (_, b, c) = crate::adjust::adjust_with_block(
                tracks,
                block,
                Gauge::RotationOnly,
                &mut poses,
                &mut points,
                &keep,
                g.loss(),
                g.max_iterations,
                last && held.iter().any(|h| !h),
            )?;
            cov = c;
            k = crate::adjust::intrinsics_of_block(&k, &b);
            k.validate().map_err(|e| {
                VisionError::Degenerate(format!("the solved lens is not usable: {e}"))
            })?;
            if !k.is_pinhole() {
                und = undistort_tracks(tracks, &k)?;
            }
            for (r, p) in rotations.iter_mut().zip(&poses) {
                *r = p.as_ref().expect("every frame posed").r;
            }
            // Directions stay unit vectors (the adjustment may slide them along their rays).
            for x in points.iter_mut().flatten() {
                *x = x.normalize();
            }
            tolerance = threshold;
        }
        stages.push(StageTime::new("rotation adjustment", t0));
    }
    progress("rotations", 1, 1);
    let poses: Vec<Option<Pose>> = rotations
        .iter()
        .map(|r| Some(Pose::new(*r, Vector3::zeros())))
        .collect();
    let mut solve = crate::pipeline::finish_solve(
        &und,
        &k.pinhole(),
        &poses,
        &points,
        tolerance,
        stages,
        false,
    )?;
    solve.report.rotation_only = true;
    if !held[0] {
        solve
            .report
            .with_free_focal_sd(&und, &k.pinhole(), &poses, &points, tolerance);
    }
    if held.iter().any(|h| !h) {
        solve.report.intrinsics = crate::adjust::solved_intrinsics(&k, held, cov.as_ref());
    }
    solve.report.notes.push(match parallax {
        Some(p) => p.describe(),
        None => "rotation-only solve (solve: tripod)".into(),
    });
    solve.report.notes.push(
        "nodal pan: every camera centre is the origin and the points are directions (on the \
         unit sphere); set the scene's scale and ground from marks or a known distance"
            .into(),
    );
    solve.path.intrinsics = Some(k);
    Ok(solve)
}
