//! RANSAC resection (the book's `ransac_singlecam`, §4.10/§7): 6-point normalized DLT on random
//! minimal samples, reprojection error in pixels as residual, and the DLT of the consensus set.

use nalgebra::{Matrix3x4, Point2, Point3};
use rand::Rng;

use super::dlt::{dlt, DLT_MIN_POINTS};
use super::factor::factor_camera;
use super::restricted::{refine_camera, IntrinsicsModel};
use crate::camera::{Camera, Intrinsics};
use crate::error::{check_pairs, Result};
use crate::optimize::LmOptions;
use crate::ransac::{ransac, Estimator, RansacParams};

/// Reprojection error in pixels of X ↔ x under P (∞ when X projects to infinity).
pub fn reprojection_error_p(p: &Matrix3x4<f64>, x3: &Point3<f64>, x2: &Point2<f64>) -> f64 {
    let h = p * x3.to_homogeneous();
    if h.z.abs() <= 1e-14 * h.norm() {
        return f64::INFINITY;
    }
    ((h.x / h.z - x2.x).powi(2) + (h.y / h.z - x2.y).powi(2)).sqrt()
}

/// The normalized DLT as a RANSAC estimator over 3D↔2D matches.
#[derive(Clone, Copy, Debug, Default)]
pub struct DltEstimator;

impl Estimator for DltEstimator {
    type Datum = (Point3<f64>, Point2<f64>);
    type Model = Matrix3x4<f64>;
    const MIN_SAMPLES: usize = DLT_MIN_POINTS;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model> {
        let p3: Vec<_> = sample.iter().map(|&i| data[i].0).collect();
        let p2: Vec<_> = sample.iter().map(|&i| data[i].1).collect();
        dlt(&p3, &p2).into_iter().collect()
    }

    fn residual(&self, p: &Self::Model, d: &Self::Datum) -> f64 {
        reprojection_error_p(p, &d.0, &d.1)
    }
}

/// Result of [`resect_ransac`].
#[derive(Clone, Debug, PartialEq)]
pub struct Resection {
    /// The camera matrix (DLT of the consensus set), ‖P‖ = 1.
    pub p: Matrix3x4<f64>,
    /// Inlier flags.
    pub inliers: Vec<bool>,
    /// Number of inliers.
    pub num_inliers: usize,
    /// RANSAC iterations.
    pub iterations: usize,
}

/// RANSAC resection of a camera from 3D↔2D matches (the book's `ransac_singlecam`) with an
/// adaptive iteration count; `params.threshold` is in pixels.
pub fn resect_ransac<R: Rng + ?Sized>(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    params: &RansacParams,
    rng: &mut R,
) -> Result<Resection> {
    check_pairs(points3d.len(), points2d.len(), DLT_MIN_POINTS)?;
    let data: Vec<_> = points3d
        .iter()
        .copied()
        .zip(points2d.iter().copied())
        .collect();
    let r = ransac(&DltEstimator, &data, params, rng)?;
    Ok(Resection {
        p: r.model,
        inliers: r.inliers,
        num_inliers: r.num_inliers,
        iterations: r.iterations,
    })
}

/// Result of [`resect_known_k`].
#[derive(Clone, Debug, PartialEq)]
pub struct PoseEstimate {
    /// The camera: the given K and the estimated [R|t].
    pub camera: Camera,
    /// Inlier flags.
    pub inliers: Vec<bool>,
    /// Number of inliers.
    pub num_inliers: usize,
    /// RANSAC iterations.
    pub iterations: usize,
}

/// Pose of a camera with known K from 3D↔2D matches with outliers (the PnP problem): RANSAC
/// resection, factoring of the consensus DLT with K′ replaced by the known K (as the book's
/// matchmove does, §7), then Levenberg–Marquardt on the pose over the inliers, whose set is
/// re-marked with the refined camera.
pub fn resect_known_k<R: Rng + ?Sized>(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    k: &Intrinsics,
    params: &RansacParams,
    rng: &mut R,
) -> Result<PoseEstimate> {
    k.validate()?;
    let res = resect_ransac(points3d, points2d, params, rng)?;
    let mut est = refine_known_k(points3d, points2d, k, &res, params.threshold)?;
    est.iterations = res.iterations;
    Ok(est)
}

/// The known-K camera of a RANSAC resection's consensus: the consensus DLT factored with K′
/// replaced by `k`, then Levenberg–Marquardt on the pose over the inliers, whose set is
/// re-marked at `threshold` pixels with the refined camera (twice at most).
pub fn refine_known_k(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    k: &Intrinsics,
    consensus: &Resection,
    threshold: f64,
) -> Result<PoseEstimate> {
    let factored = factor_camera(&consensus.p)?;
    let camera = Camera {
        intrinsics: k.clone(),
        pose: factored.pose,
    };
    refine_and_remark(
        points3d,
        points2d,
        camera,
        consensus.inliers.clone(),
        threshold,
        DLT_MIN_POINTS,
    )
}

/// Levenberg–Marquardt on the pose of `camera` (its K fixed) over the `inliers`, which are
/// re-marked at `threshold` pixels with the refined camera (twice at most; a re-marking that
/// would leave fewer than `min_inliers` is not taken).
pub(crate) fn refine_and_remark(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    mut camera: Camera,
    mut inliers: Vec<bool>,
    threshold: f64,
    min_inliers: usize,
) -> Result<PoseEstimate> {
    let lm = LmOptions {
        max_iterations: 50,
        ..LmOptions::default()
    };
    let k = camera.intrinsics.clone();
    for _ in 0..2 {
        let p3: Vec<_> = points3d
            .iter()
            .zip(&inliers)
            .filter(|(_, &f)| f)
            .map(|(p, _)| *p)
            .collect();
        let p2: Vec<_> = points2d
            .iter()
            .zip(&inliers)
            .filter(|(_, &f)| f)
            .map(|(p, _)| *p)
            .collect();
        camera = refine_camera(&p3, &p2, &camera, IntrinsicsModel::Fixed(k.clone()), &lm)?.0;
        let flags: Vec<bool> = points3d
            .iter()
            .zip(points2d)
            .map(|(p, x)| camera.reprojection_error(p, x) <= threshold)
            .collect();
        if flags == inliers || flags.iter().filter(|&&f| f).count() < min_inliers {
            break;
        }
        inliers = flags;
    }
    let num_inliers = inliers.iter().filter(|&&f| f).count();
    Ok(PoseEstimate {
        camera,
        inliers,
        num_inliers,
        iterations: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::synthetic::{observe, random_camera, random_points_in_front};
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    #[test]
    fn finds_outliers() {
        let mut rng = Pcg64::seed_from_u64(21);
        let cam = random_camera(&mut rng);
        let pts = random_points_in_front(&cam, 200, &mut rng);
        let (obs, outlier) = observe(&cam, &pts, 0.5, 0.3, &mut rng);
        let res = resect_ransac(&pts, &obs, &RansacParams::with_threshold(2.0), &mut rng).unwrap();
        let wrong = res
            .inliers
            .iter()
            .zip(&outlier)
            .filter(|(i, o)| **i && **o)
            .count();
        assert_eq!(wrong, 0);
        assert!(res.num_inliers >= 130, "{}", res.num_inliers);
        let est = resect_known_k(
            &pts,
            &obs,
            &cam.intrinsics,
            &RansacParams::with_threshold(2.0),
            &mut rng,
        )
        .unwrap();
        let er =
            crate::rotation::rotation_angle_between(&est.camera.pose.r, &cam.pose.r).to_degrees();
        assert!(er < 0.05, "{er}");
        assert!(est.inliers.iter().zip(&outlier).all(|(i, o)| !(*i && *o)));
    }
}
