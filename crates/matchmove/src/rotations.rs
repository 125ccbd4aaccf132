//! Rotations from rays, for a camera that only turns (the `tripod` solve): the rotation between
//! two sets of unit rays (Kabsch's fit, by RANSAC), the frame-by-frame chain of a pan's
//! rotations, and a pan's unknown focal length from the chained rotations' residual over focal
//! lengths ([`estimate_rotation_focal`]; a rotating camera's homographies K R K⁻¹ fix K:
//! Hartley 1997, "Self-calibration of stationary cameras").

use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::ransac::{ransac, Estimator, RansacParams};
use vfxgraph_geometry::rotation::nearest_rotation;
use vfxgraph_klt::Tracks;

use crate::structure::{derive_seed, reprojection_error};

/// RANSAC threshold of the rotation fits, px.
pub(crate) const ROTATION_THRESHOLD: f64 = 3.0;
/// Focal lengths tried by [`estimate_rotation_focal`], log-spaced over 0.3–3 diagonals.
pub(crate) const FOCAL_GRID: usize = 16;

/// A rotation R with b ≈ R·a between unit rays (a, b), fitted by Kabsch's SVD; residuals in
/// pixels of a camera of focal length `focal` (the chord between rays × f).
pub(crate) struct RotationEstimator {
    pub(crate) focal: f64,
}

impl Estimator for RotationEstimator {
    type Datum = (Vector3<f64>, Vector3<f64>);
    type Model = Matrix3<f64>;
    const MIN_SAMPLES: usize = 2;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model> {
        let mut m = Matrix3::zeros();
        for &i in sample {
            m += data[i].1 * data[i].0.transpose();
        }
        vec![nearest_rotation(&m)]
    }

    fn residual(&self, r: &Self::Model, d: &Self::Datum) -> f64 {
        self.focal * (d.1 - r * d.0).norm()
    }
}

/// The unit ray of pixel `p` of a pinhole `k`.
pub(crate) fn ray(k: &Intrinsics, p: &[f64; 2]) -> Vector3<f64> {
    let q = k.k_inv() * Vector3::new(p[0], p[1], 1.0);
    q / q.norm()
}

/// The RANSAC of a pair's rotation.
pub(crate) fn rotation_ransac() -> RansacParams {
    RansacParams::with_threshold(ROTATION_THRESHOLD)
}

/// Rotations of a pan chained frame by frame, and the tracks' directions.
pub(crate) struct Chain {
    /// R of every frame (a world direction d is seen along the ray R·d).
    pub(crate) rotations: Vec<Matrix3<f64>>,
    /// Direction of each track seen in two frames or more.
    pub(crate) directions: Vec<Option<Vector3<f64>>>,
    /// Inlier flag of every observation (by track and observation).
    pub(crate) inliers: Vec<Vec<bool>>,
}

/// Chains the rotations of `tracks` (seen by the pinhole `k`): frame 0 is the identity; each
/// next frame's rotation is fitted by RANSAC to the directions of the tracks it continues
/// (the mean of their rays so far, rotated back), and its inlier rays join the means.
pub(crate) fn chain(tracks: &Tracks, k: &Intrinsics, seed: u64) -> Result<Chain> {
    let n = tracks.frames.len();
    let rays: Vec<Vec<Vector3<f64>>> = tracks
        .tracks
        .iter()
        .map(|t| t.points.iter().map(|p| ray(k, p)).collect())
        .collect();
    let mut seen: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (ti, t) in tracks.tracks.iter().enumerate() {
        for j in 0..t.points.len() {
            seen[t.first + j].push((ti, j));
        }
    }
    let mut sums = vec![Vector3::zeros(); tracks.tracks.len()];
    let mut counts = vec![0usize; tracks.tracks.len()];
    let mut inliers: Vec<Vec<bool>> = tracks
        .tracks
        .iter()
        .map(|t| vec![false; t.points.len()])
        .collect();
    let mut rotations = vec![Matrix3::identity(); n];
    let est = RotationEstimator { focal: k.f1 };
    for i in 0..n {
        let (known, new): (Vec<_>, Vec<_>) = seen[i].iter().partition(|(ti, _)| counts[*ti] > 0);
        if i > 0 {
            let data: Vec<_> = known
                .iter()
                .map(|&(ti, j)| (sums[ti].normalize(), rays[ti][j]))
                .collect();
            if data.len() < 3 {
                return Err(VisionError::Degenerate(format!(
                    "frame {}: {} tracks continue from the frames before; a rotation needs 3",
                    tracks.frames[i],
                    data.len()
                )));
            }
            let mut rng = Pcg64::seed_from_u64(derive_seed(seed, 12, i as u64));
            let params = RansacParams::with_threshold(ROTATION_THRESHOLD);
            let fit = ransac(&est, &data, &params, &mut rng)?;
            rotations[i] = fit.model;
            for (&(ti, j), &ok) in known.iter().zip(&fit.inliers) {
                if ok {
                    sums[ti] += fit.model.transpose() * rays[ti][j];
                    counts[ti] += 1;
                    inliers[ti][j] = true;
                }
            }
        }
        let r = rotations[i];
        for &(ti, j) in if i == 0 { &seen[0] } else { &new } {
            sums[ti] += r.transpose() * rays[ti][j];
            counts[ti] += 1;
            inliers[ti][j] = true;
        }
    }
    let directions = sums
        .iter()
        .zip(&counts)
        .map(|(s, &c)| (c >= 2).then(|| s.normalize()))
        .collect();
    Ok(Chain {
        rotations,
        directions,
        inliers,
    })
}

/// The focal length (px) whose chained rotations fit the tracks best (module docs): the mean
/// squared pixel residual of [`chain`], each residual truncated at the RANSAC threshold, on a
/// logarithmic grid of [`FOCAL_GRID`] focal lengths from 0.3 to 3 image diagonals (in
/// parallel), then the parabola through the best and its neighbours; the adjustment refines it.
pub fn estimate_rotation_focal(tracks: &Tracks, k: &Intrinsics, seed: u64) -> Result<f64> {
    let diag = crate::grid::image_diagonal(k)?;
    let cost = |f: f64| -> f64 {
        let kf = Intrinsics {
            f1: f,
            f2: f * k.f2 / k.f1,
            ..k.pinhole()
        };
        let Ok(c) = chain(tracks, &kf, seed) else {
            return f64::INFINITY;
        };
        let (mut s, mut m) = (0.0, 0usize);
        for (t, d) in tracks.tracks.iter().zip(&c.directions) {
            let Some(d) = d else { continue };
            for (j, p) in t.points.iter().enumerate() {
                let pose = Pose::new(c.rotations[t.first + j], Vector3::zeros());
                let e = reprojection_error(&kf, &pose, d, p).min(ROTATION_THRESHOLD);
                s += e * e;
                m += 1;
            }
        }
        if m == 0 {
            f64::INFINITY
        } else {
            s / m as f64
        }
    };
    let Some(f) = crate::grid::log_grid_minimum(0.3 * diag, 3.0 * diag, FOCAL_GRID, &cost) else {
        return Err(VisionError::Degenerate(
            "the pan's rotations cannot be chained at any focal length".into(),
        ));
    };
    // A camera that hardly turns fits every focal length alike.
    let kf = Intrinsics {
        f1: f,
        f2: f * k.f2 / k.f1,
        ..k.pinhole()
    };
    let c = chain(tracks, &kf, seed)?;
    let turn = c
        .rotations
        .iter()
        .map(|r| {
            vfxgraph_geometry::rotation::r_to_axis_angle(r)
                .norm()
                .to_degrees()
        })
        .fold(0.0, f64::max);
    if turn < MIN_TURN_DEGREES {
        return Err(VisionError::Degenerate(format!(
            "the camera hardly turns (at most {turn:.2}° from the first frame): a pan's focal \
             length cannot be measured; give it with focal: known or refine"
        )));
    }
    Ok(f)
}

/// The least turn from the first frame that measures a pan's focal length, degrees.
const MIN_TURN_DEGREES: f64 = 2.0;

/// The direction of a track from its inlier observations in the cameras `rotations`: the
/// normalized mean of its rays rotated back (the rotation-only triangulation).
pub(crate) fn direction(
    k: &Intrinsics,
    track: &vfxgraph_klt::Track,
    rotations: &[Matrix3<f64>],
    keep: &[bool],
) -> Option<Vector3<f64>> {
    let mut s = Vector3::zeros();
    let mut c = 0;
    for (j, p) in track.points.iter().enumerate() {
        if keep[j] {
            s += rotations[track.first + j].transpose() * ray(k, p);
            c += 1;
        }
    }
    (c >= 2 && s.norm() > 0.0).then(|| s.normalize())
}
