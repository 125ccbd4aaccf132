//! Cameras for frames no fragment solved (not in the book, which discards its last fragment):
//! each unposed frame next to a posed one is resected from the reconstructed points it observes
//! (RANSAC on P3P with K known, then refined: sound on a planar set), and tracks that gain enough posed observations are
//! triangulated, sweeping outwards until every frame has a camera or no frame can be resected.

use nalgebra::{Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vfxgraph_geometry::calibration::resect_p3p;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::ransac::RansacParams;
use vfxgraph_klt::Tracks;

use crate::structure::{reprojection_error, triangulate_views};

/// Resection threshold, pixels.
const RESECTION_TOLERANCE: f64 = 4.0;
/// Fewest inlier points to accept a resected camera.
const MIN_RESECTION_INLIERS: usize = 8;
/// A new point must reproject within this in every posed frame, pixels.
const TRIANGULATION_TOLERANCE: f64 = 3.0;
/// …and be seen from directions at least this far apart, degrees.
const MIN_PARALLAX_DEG: f64 = 1.0;

/// Triangulates every track without a point that is observed in ≥ 3 posed frames with enough
/// parallax and reprojects within tolerance everywhere.
pub(crate) fn triangulate_new_tracks(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &mut [Option<Vector3<f64>>],
) {
    for (ti, t) in tracks.tracks.iter().enumerate() {
        if points[ti].is_some() {
            continue;
        }
        let views: Vec<(&Pose, [f64; 2])> = t
            .points
            .iter()
            .enumerate()
            .filter_map(|(j, o)| poses.get(t.first + j)?.as_ref().map(|p| (p, *o)))
            .collect();
        if views.len() < 3 {
            continue;
        }
        let Some(x) = triangulate_views(k, &views) else {
            continue;
        };
        if views
            .iter()
            .any(|(p, o)| reprojection_error(k, p, &x, o) > TRIANGULATION_TOLERANCE)
        {
            continue;
        }
        let (ca, cb) = (views[0].0.center(), views[views.len() - 1].0.center());
        let angle = vfxgraph_geometry::two_view::parallax_angle(&ca, &cb, &Point3::from(x));
        if angle.to_degrees() < MIN_PARALLAX_DEG {
            continue;
        }
        points[ti] = Some(x);
    }
}

/// Resects frame `f` from the points it observes; `None` if too few agree.
fn resect_frame(
    tracks: &Tracks,
    k: &Intrinsics,
    points: &[Option<Vector3<f64>>],
    f: usize,
    rng: &mut Pcg64,
) -> Option<Pose> {
    let (mut p3, mut p2) = (Vec::new(), Vec::new());
    for (t, x) in tracks.tracks.iter().zip(points) {
        if let (Some(x), Some(o)) = (x, t.at(f)) {
            p3.push(Point3::from(*x));
            p2.push(Point2::new(o[0], o[1]));
        }
    }
    if p3.len() < MIN_RESECTION_INLIERS {
        return None;
    }
    let params = RansacParams {
        threshold: RESECTION_TOLERANCE,
        max_iterations: 1000,
        ..RansacParams::default()
    };
    let est = resect_p3p(&p3, &p2, k, &params, rng).ok()?;
    (est.num_inliers >= MIN_RESECTION_INLIERS).then_some(est.camera.pose)
}

/// Gives every frame a camera (module docs); the frames that cannot be resected are an error.
pub fn extend_to_all_frames(
    tracks: &Tracks,
    k: &Intrinsics,
    mut poses: Vec<Option<Pose>>,
    mut points: Vec<Option<Vector3<f64>>>,
    seed: u64,
) -> Result<crate::structure::Structure> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let n = poses.len();
    if poses.iter().all(|p| p.is_some()) {
        return Ok((poses, points));
    }
    loop {
        let mut progressed = false;
        for f in 0..n {
            if poses[f].is_some() {
                continue;
            }
            let near = (f > 0 && poses[f - 1].is_some()) || (f + 1 < n && poses[f + 1].is_some());
            if !near {
                continue;
            }
            if let Some(p) = resect_frame(tracks, k, &points, f, &mut rng) {
                poses[f] = Some(p);
                progressed = true;
                triangulate_new_tracks(tracks, k, &poses, &mut points);
            }
        }
        if !progressed {
            break;
        }
    }
    let missing: Vec<i64> = (0..n)
        .filter(|&f| poses[f].is_none())
        .map(|f| tracks.frames[f])
        .collect();
    if !missing.is_empty() {
        return Err(VisionError::Degenerate(format!(
            "{} frames could not be given a camera (too few reconstructed points seen): {}{}",
            missing.len(),
            missing
                .iter()
                .take(10)
                .map(|f| f.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            if missing.len() > 10 { ", …" } else { "" }
        )));
    }
    Ok((poses, points))
}
