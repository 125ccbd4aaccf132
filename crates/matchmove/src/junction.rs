//! Scale compatibility and junction of fragments (book §7.12).
//!
//! Each fragment is solved in its own frame and scale (its best pair has a unit baseline).
//! Neighbouring fragments share one frame. For a trial scale s of the next fragment, its
//! reference is changed so that its first camera coincides with the previous fragment's last
//! camera and its translations are multiplied by s; the previous fragment's points are
//! reprojected into the next fragment's frames, and a point counts if its error is below
//! `tolerance` (20 px) in every frame that observes it. The scale with the most such points (and,
//! among equals, the least mean error) over a geometric progression (×1.01 from `min_scale` to
//! `max_scale`) is refined by Brent's method on the mean error of those points.
//!
//! Chaining the reference changes and multiplying the scales puts every fragment in the first
//! fragment's frame and scale. The book's program used only the points tracked through both
//! fragments; we use every point of the previous fragment observed in the next one's frames, in
//! the frames where it is observed — the same cost, on more evidence.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::optimize::brent_minimize;
use vfxgraph_klt::Tracks;
use vfxgraph_params::Options;

use crate::fragment::FragmentSolution;
use crate::structure::reprojection_error;

/// The scale search's constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
#[param(check)]
pub struct ScaleOptions {
    /// smallest relative scale tried (§7.12)
    ///
    /// The book's ε.
    #[param(name = "scale_min", range = 1e-9..=1e9)]
    pub min_scale: f64,
    /// largest relative scale tried (§7.12)
    ///
    /// Book: 100.
    #[param(name = "scale_max", range = 1e-9..=1e9)]
    pub max_scale: f64,
    /// ratio of the scale progression (§7.12)
    ///
    /// Of the geometric progression (book: 1.01).
    #[param(name = "scale_step", range = 1.000_001..=10.0)]
    pub step: f64,
    /// a point agrees with a scale if its error is below this in every frame, px
    ///
    /// Book: 20.
    #[param(name = "scale_tolerance", range = 1e-3..=1e5)]
    pub tolerance: f64,
    /// Fewer agreeing points than this is an error.
    #[param(skip)]
    pub min_points: usize,
}

impl Default for ScaleOptions {
    fn default() -> Self {
        ScaleOptions {
            min_scale: 1e-3,
            max_scale: 100.0,
            step: 1.01,
            tolerance: 20.0,
            min_points: 3,
        }
    }
}

impl ScaleOptions {
    /// The range of scales is not empty.
    pub fn check(&self) -> std::result::Result<(), String> {
        if self.min_scale >= self.max_scale {
            return Err("`scale_min` must be below `scale_max`".into());
        }
        Ok(())
    }
}

/// The fragments joined in the first fragment's frame.
#[derive(Clone, Debug)]
pub struct Joined {
    /// Poses by frame index (`None` where no fragment reached).
    pub poses: Vec<Option<Pose>>,
    /// Points by track index.
    pub points: Vec<Option<Vector3<f64>>>,
    /// Scale of each fragment relative to the first (cumulative).
    pub scales: Vec<f64>,
}

/// The change of reference of fragment B onto A's last camera `(ra, ta)` at scale `s`: the
/// transformed pose of B's frame f, given B's first pose `(rb0, tb0)`.
fn moved_pose(
    ra: &Matrix3<f64>,
    ta: &Vector3<f64>,
    rb0: &Matrix3<f64>,
    tb0: &Vector3<f64>,
    p: &Pose,
    s: f64,
) -> Pose {
    let m = p.r * rb0.transpose();
    Pose::new(m * ra, m * ta + s * (p.t - m * tb0))
}

/// A point of B in A's frame: X_A = R_aᵀ(s(R_b0 X_B + t_b0) − t_a).
fn moved_point(
    ra: &Matrix3<f64>,
    ta: &Vector3<f64>,
    rb0: &Matrix3<f64>,
    tb0: &Vector3<f64>,
    x: &Vector3<f64>,
    s: f64,
) -> Vector3<f64> {
    ra.transpose() * (s * (rb0 * x + tb0) - ta)
}

/// Joins solved fragments (in sequence order) into the first one's frame and scale.
pub fn join_fragments(
    tracks: &Tracks,
    k: &Intrinsics,
    solutions: &[FragmentSolution],
    options: &ScaleOptions,
) -> Result<Joined> {
    let n = tracks.frames.len();
    let mut poses: Vec<Option<Pose>> = vec![None; n];
    let mut points: Vec<Option<Vector3<f64>>> = vec![None; tracks.tracks.len()];
    let mut scales = Vec::with_capacity(solutions.len());
    let Some(first) = solutions.first() else {
        return Ok(Joined {
            poses,
            points,
            scales,
        });
    };
    let range = first.fragment.first..=first.fragment.last;
    poses[range.clone()].clone_from_slice(&first.poses[range]);
    points.clone_from(&first.points);
    scales.push(1.0);
    let mut cumulative = 1.0;
    // Points of the previous fragment, already in the global frame.
    let mut prev_points = first.points.clone();
    for (idx, b) in solutions.iter().enumerate().skip(1) {
        let bf = &b.fragment;
        let shared_frame = bf.first;
        let (ra, ta) = match &poses[shared_frame] {
            Some(p) => (p.r, p.t),
            None => {
                return Err(VisionError::Degenerate(format!(
                    "fragment {idx} starts at frame {} which no previous fragment solved",
                    tracks.frames[shared_frame]
                )))
            }
        };
        let b0 = b.poses[shared_frame].as_ref().expect("fragment pose");
        let (rb0, tb0) = (b0.r, b0.t);
        // Evidence: previous points with their observations in B's frames.
        type Evidence = (Vector3<f64>, Vec<(usize, [f64; 2])>);
        let evidence: Vec<Evidence> = tracks
            .tracks
            .iter()
            .zip(&prev_points)
            .filter_map(|(t, x)| {
                let x = (*x)?;
                let obs: Vec<(usize, [f64; 2])> = (bf.first + 1..=bf.last)
                    .filter_map(|f| t.at(f).map(|o| (f, o)))
                    .collect();
                (!obs.is_empty()).then_some((x, obs))
            })
            .collect();
        let moved: Vec<Option<Pose>> = (0..n)
            .map(|f| {
                if f > bf.first && f <= bf.last {
                    b.poses[f].clone()
                } else {
                    None
                }
            })
            .collect();
        // (count, mean error) of the agreeing points at relative scale r, and their indices.
        let evaluate = |r: f64, only: Option<&[usize]>| -> (usize, f64, Vec<usize>) {
            let s = cumulative * r;
            let cams: Vec<Option<Pose>> = moved
                .iter()
                .map(|p| p.as_ref().map(|p| moved_pose(&ra, &ta, &rb0, &tb0, p, s)))
                .collect();
            let (mut count, mut sum, mut m) = (0usize, 0.0, 0usize);
            let mut agreeing = Vec::new();
            let candidates: Box<dyn Iterator<Item = usize>> = match only {
                Some(v) => Box::new(v.iter().copied()),
                None => Box::new(0..evidence.len()),
            };
            for i in candidates {
                let (x, obs) = &evidence[i];
                let errs: Vec<f64> = obs
                    .iter()
                    .map(|(f, o)| reprojection_error(k, cams[*f].as_ref().unwrap(), x, o))
                    .collect();
                if only.is_some() || errs.iter().all(|e| *e < options.tolerance) {
                    count += 1;
                    agreeing.push(i);
                    for e in errs {
                        sum += e.min(options.tolerance * 10.0);
                        m += 1;
                    }
                }
            }
            (
                count,
                if m > 0 { sum / m as f64 } else { f64::INFINITY },
                agreeing,
            )
        };
        let mut best = (0usize, f64::INFINITY, 1.0f64);
        let mut r = options.min_scale;
        while r <= options.max_scale {
            let (c, e, _) = evaluate(r, None);
            if c > best.0 || (c == best.0 && e < best.1) {
                best = (c, e, r);
            }
            r *= options.step;
        }
        if best.0 < options.min_points {
            return Err(VisionError::Degenerate(format!(
                "fragments ending and starting at frame {}: only {} shared points agree on any \
                 scale (at least {} needed)",
                tracks.frames[shared_frame], best.0, options.min_points
            )));
        }
        let (_, _, agreeing) = evaluate(best.2, None);
        let refined = brent_minimize(
            |r| evaluate(r, Some(&agreeing)).1,
            best.2 / options.step,
            best.2 * options.step,
            1e-6,
            100,
        )
        .map(|m| m.x)
        .unwrap_or(best.2);
        cumulative *= refined;
        scales.push(cumulative);
        let s = cumulative;
        for (f, pose) in poses
            .iter_mut()
            .enumerate()
            .take(bf.last + 1)
            .skip(bf.first + 1)
        {
            *pose = b.poses[f]
                .as_ref()
                .map(|p| moved_pose(&ra, &ta, &rb0, &tb0, p, s));
        }
        let mut next_points = vec![None; tracks.tracks.len()];
        for (ti, x) in b.points.iter().enumerate() {
            if let Some(x) = x {
                let g = moved_point(&ra, &ta, &rb0, &tb0, x, s);
                next_points[ti] = Some(g);
                if points[ti].is_none() {
                    points[ti] = Some(g);
                }
            }
        }
        prev_points = next_points;
    }
    Ok(Joined {
        poses,
        points,
        scales,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use vfxgraph_geometry::rotation::axis_angle_to_r;

    /// Moving B onto A's last camera keeps the image of every point: projecting a B point with a
    /// B camera equals projecting the moved point with the moved camera, for any scale.
    #[test]
    fn change_of_reference_preserves_projections() {
        let k = Intrinsics::new(800.0, 800.0, 320.0, 240.0);
        let ra = axis_angle_to_r(&Vector3::new(0.1, -0.2, 0.05));
        let ta = Vector3::new(0.3, -0.1, 2.0);
        let rb0 = axis_angle_to_r(&Vector3::new(-0.05, 0.1, 0.2));
        let tb0 = Vector3::new(-0.2, 0.4, 0.1);
        let p = Pose::new(
            axis_angle_to_r(&Vector3::new(0.02, 0.3, -0.1)),
            Vector3::new(0.5, 0.1, -0.3),
        );
        let x = Vector3::new(0.4, -0.3, 5.0);
        for s in [0.5, 1.0, 3.7] {
            let a = crate::structure::project(&k, &p, &x).unwrap();
            let mp = moved_pose(&ra, &ta, &rb0, &tb0, &p, s);
            let mx = moved_point(&ra, &ta, &rb0, &tb0, &x, s);
            let b = crate::structure::project(&k, &mp, &mx).unwrap();
            assert!(
                (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9,
                "{a:?} {b:?}"
            );
            // B's first camera lands on A's last one.
            let m0 = moved_pose(&ra, &ta, &rb0, &tb0, &Pose::new(rb0, tb0), s);
            assert!((m0.r - ra).norm() < 1e-12 && (m0.t - ta).norm() < 1e-12);
        }
    }
}
