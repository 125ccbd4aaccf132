//! Calibration with a planar pattern (book §4.8, after Tsai 1987 as revisited by Horn): the
//! target lies on the plane z = 0, the principal point is known and K = diag(f, f, 1) + (u0, v0).
//! A homogeneous linear system (eq. 4.27) gives r11, r12, r21, r22, t1, t2 up to scale; the scale λ
//! is the largest root of eq. 4.35; r13, r23 follow up to a common sign, fixed by requiring f > 0
//! and the target in front of the camera; f and t3 come from linear least squares; then
//! Levenberg–Marquardt refines (f, R, t) on the reprojection error.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix3x4, Point2, Point3, Vector3};

use super::restricted::{refine_camera, IntrinsicsModel};
use crate::camera::{Camera, Intrinsics};
use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::optimize::{linear_least_squares, min_norm_on_sphere, LmOptions, LmReport};
use crate::ransac::Estimator;
use crate::rotation::nearest_rotation;

/// Minimum number of matches of Tsai's linear step (book §4.8).
pub const TSAI_MIN_POINTS: usize = 6;

fn check_planar(points3d: &[Point3<f64>]) -> Result<()> {
    let extent = points3d
        .iter()
        .map(|p| p.coords.xy().norm())
        .fold(0.0, f64::max);
    if points3d
        .iter()
        .any(|p| p.z.abs() > 1e-9 * extent.max(1e-300))
    {
        return Err(VisionError::InvalidInput(
            "Tsai's calibration needs a planar target on z = 0".into(),
        ));
    }
    Ok(())
}

/// Tsai's linear calibration (book §4.8) from ≥ 6 matches of points on z = 0 with their pixels,
/// given the principal point. Returns K = [[f, 0, u0], [0, f, v0], [0, 0, 1]] and [R|t].
pub fn tsai(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    principal_point: Point2<f64>,
) -> Result<Camera> {
    check_pairs(points3d.len(), points2d.len(), TSAI_MIN_POINTS)?;
    check_finite("3D points", points3d.iter().flat_map(|p| p.coords.iter()))?;
    check_finite("2D points", points2d.iter().flat_map(|p| p.coords.iter()))?;
    check_planar(points3d)?;
    check_finite("principal point", principal_point.coords.iter())?;
    let n = points3d.len();
    // Centred pixels (eq. 4.23); scale the target for conditioning (the system is homogeneous in
    // x', so scaling x' is harmless; scaling X by 1/β scales r̂ by β).
    let xp: Vec<Vector3<f64>> = points2d
        .iter()
        .map(|x| Vector3::new(x.x - principal_point.x, x.y - principal_point.y, 0.0))
        .collect();
    let beta = (points3d
        .iter()
        .map(|p| p.coords.xy().norm_squared())
        .sum::<f64>()
        / n as f64)
        .sqrt();
    let alpha = (xp.iter().map(|x| x.norm_squared()).sum::<f64>() / n as f64).sqrt();
    if !(beta > 0.0) || !(alpha > 0.0) {
        return Err(VisionError::Degenerate(
            "all target points or all pixels coincide".into(),
        ));
    }
    let mut a = DMatrix::zeros(n, 6);
    for i in 0..n {
        let (x, y) = (points3d[i].x / beta, points3d[i].y / beta);
        let (u, v) = (xp[i].x / alpha, xp[i].y / alpha);
        let row = [x * v, y * v, v, -x * u, -y * u, -u];
        for (k, val) in row.iter().enumerate() {
            a[(i, k)] = *val;
        }
    }
    let nv = min_norm_on_sphere(&a)?;
    if nv.is_ambiguous(1e-9) {
        return Err(VisionError::Degenerate(
            "Tsai's linear system has more than one solution (collinear target?)".into(),
        ));
    }
    let s = &nv.x;
    let (mut r11, mut r12, mut t1, mut r21, mut r22, mut t2) = (
        s[0] / beta,
        s[1] / beta,
        s[2],
        s[3] / beta,
        s[4] / beta,
        s[5],
    );
    // Overall sign: the predicted and observed centred pixels point the same way (eq. 4.39).
    let agree: f64 = points3d
        .iter()
        .zip(&xp)
        .map(|(p, x)| {
            ((r11 * p.x + r12 * p.y + t1) * x.x + (r21 * p.x + r22 * p.y + t2) * x.y).signum()
        })
        .sum();
    if agree < 0.0 {
        for v in [&mut r11, &mut r12, &mut t1, &mut r21, &mut r22, &mut t2] {
            *v = -*v;
        }
    }
    // λ² is the largest root of eq. 4.35.
    let sum = r11 * r11 + r12 * r12 + r21 * r21 + r22 * r22;
    let det = r11 * r22 - r12 * r21;
    let disc = (sum * sum - 4.0 * det * det).max(0.0);
    let lambda2 = 0.5 * (sum + disc.sqrt());
    if !(lambda2 > 0.0) {
        return Err(VisionError::Degenerate("Tsai: zero scale".into()));
    }
    let lambda = lambda2.sqrt();
    let r13 = (lambda2 - r11 * r11 - r12 * r12).max(0.0).sqrt();
    let mut r23 = (lambda2 - r21 * r21 - r22 * r22).max(0.0).sqrt();
    if r11 * r21 + r12 * r22 > 0.0 {
        r23 = -r23; // eq. 4.38: r13 r23 = −(r11 r21 + r12 r22)
    }
    let t12 = (t1 / lambda, t2 / lambda);
    let mut best: Option<(f64, Camera)> = None;
    for sign in [1.0, -1.0] {
        let row1 = Vector3::new(r11, r12, sign * r13) / lambda;
        let row2 = Vector3::new(r21, r22, sign * r23) / lambda;
        let row3 = row1.cross(&row2);
        let r = nearest_rotation(&Matrix3::from_rows(&[
            row1.transpose(),
            row2.transpose(),
            row3.transpose(),
        ]));
        // f and t3 by least squares (the last system of §4.8).
        let mut m = DMatrix::zeros(2 * n, 2);
        let mut b = DVector::zeros(2 * n);
        for (i, (p, x)) in points3d.iter().zip(&xp).enumerate() {
            let c1 = r[(0, 0)] * p.x + r[(0, 1)] * p.y + t12.0;
            let c2 = r[(1, 0)] * p.x + r[(1, 1)] * p.y + t12.1;
            let c3 = r[(2, 0)] * p.x + r[(2, 1)] * p.y;
            m[(2 * i, 0)] = c1;
            m[(2 * i, 1)] = -x.x;
            b[2 * i] = c3 * x.x;
            m[(2 * i + 1, 0)] = c2;
            m[(2 * i + 1, 1)] = -x.y;
            b[2 * i + 1] = c3 * x.y;
        }
        let Ok(sol) = linear_least_squares(&m, &b) else {
            continue;
        };
        let (f, t3) = (sol[0], sol[1]);
        if !(f > 0.0) {
            continue;
        }
        let k = Intrinsics::new(f, f, principal_point.x, principal_point.y);
        let cam = Camera::new(k, r, Vector3::new(t12.0, t12.1, t3));
        if points3d.iter().any(|p| cam.depth(p) <= 0.0) {
            continue;
        }
        let err: f64 = points3d
            .iter()
            .zip(points2d)
            .map(|(p, x)| cam.reprojection_error(p, x).powi(2))
            .sum();
        if best.as_ref().is_none_or(|(e, _)| err < *e) {
            best = Some((err, cam));
        }
    }
    best.map(|b| b.1).ok_or_else(|| {
        VisionError::Degenerate(
            "Tsai: no solution with f > 0 in front of the camera (fronto-parallel target?)".into(),
        )
    })
}

/// Tsai's calibration followed by its Levenberg–Marquardt refinement of (f, R, t) with the
/// principal point fixed (book §4.8, last paragraph).
pub fn tsai_refine(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    principal_point: Point2<f64>,
    options: &LmOptions,
) -> Result<(Camera, LmReport)> {
    let start = tsai(points3d, points2d, principal_point)?;
    let model = IntrinsicsModel::SingleFocal {
        u0: principal_point.x,
        v0: principal_point.y,
    };
    refine_camera(points3d, points2d, &start, model, options)
}

/// Tsai's calibration as a RANSAC estimator (planar targets with outliers); the model is P.
#[derive(Clone, Debug)]
pub struct TsaiEstimator {
    /// The known principal point.
    pub principal_point: Point2<f64>,
}

impl Estimator for TsaiEstimator {
    type Datum = (Point3<f64>, Point2<f64>);
    type Model = Matrix3x4<f64>;
    const MIN_SAMPLES: usize = TSAI_MIN_POINTS;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model> {
        let p3: Vec<_> = sample.iter().map(|&i| data[i].0).collect();
        let p2: Vec<_> = sample.iter().map(|&i| data[i].1).collect();
        tsai(&p3, &p2, self.principal_point)
            .map(|c| c.p_matrix())
            .into_iter()
            .collect()
    }

    fn residual(&self, p: &Self::Model, d: &Self::Datum) -> f64 {
        super::resection::reprojection_error_p(p, &d.0, &d.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::synthetic::{gaussian, random_rotation};
    use crate::rotation::rotation_angle_between;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn planar_scene(
        seed: u64,
        n: usize,
        sigma: f64,
    ) -> (Camera, Vec<Point3<f64>>, Vec<Point2<f64>>) {
        let mut rng = Pcg64::seed_from_u64(seed);
        let f = rng.random_range(800.0..1600.0);
        let k = Intrinsics::new(
            f,
            f,
            639.5 + rng.random_range(-20.0..20.0),
            359.5 + rng.random_range(-20.0..20.0),
        );
        // Target tilted 20–50° from fronto-parallel.
        let tilt = nalgebra::Rotation3::from_axis_angle(
            &Vector3::x_axis(),
            rng.random_range(30f64..60.0).to_radians(),
        );
        let r = random_rotation(&mut rng, 0.3) * tilt.matrix();
        let t = Vector3::new(
            rng.random_range(-0.2..0.2),
            rng.random_range(-0.2..0.2),
            rng.random_range(3.0..5.0),
        );
        let cam = Camera::new(k, r, t);
        let mut p3 = Vec::new();
        let mut p2 = Vec::new();
        while p3.len() < n {
            let p = Point3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                0.0,
            );
            if let Ok(x) = cam.project(&p) {
                if x.x >= 0.0 && x.x < 1280.0 && x.y >= 0.0 && x.y < 720.0 {
                    p3.push(p);
                    p2.push(Point2::new(
                        x.x + sigma * gaussian(&mut rng),
                        x.y + sigma * gaussian(&mut rng),
                    ));
                }
            }
        }
        (cam, p3, p2)
    }

    #[test]
    fn exact_planar_data() {
        let (cam, p3, p2) = planar_scene(1, 30, 0.0);
        let pp = Point2::new(cam.intrinsics.u0, cam.intrinsics.v0);
        let est = tsai(&p3, &p2, pp).unwrap();
        assert!((est.intrinsics.f1 - cam.intrinsics.f1).abs() < 1e-6 * cam.intrinsics.f1);
        assert!(rotation_angle_between(&est.pose.r, &cam.pose.r) < 1e-9);
        assert!((est.pose.t - cam.pose.t).norm() < 1e-9);
    }

    /// Must-show: Tsai + LM recovers f within 0.5 % and the rotation within 0.05° (0.5 px noise).
    #[test]
    fn tsai_with_noise_recovers_ground_truth() {
        let mut worst = [0.0f64; 2];
        for seed in 0..10 {
            let (cam, p3, p2) = planar_scene(200 + seed, 300, 0.5);
            let pp = Point2::new(cam.intrinsics.u0, cam.intrinsics.v0);
            let (est, _) = tsai_refine(&p3, &p2, pp, &LmOptions::default()).unwrap();
            let ef = ((est.intrinsics.f1 - cam.intrinsics.f1) / cam.intrinsics.f1).abs();
            let er = rotation_angle_between(&est.pose.r, &cam.pose.r).to_degrees();
            worst[0] = worst[0].max(ef);
            worst[1] = worst[1].max(er);
            assert!(ef < 0.005 && er < 0.05, "seed {seed}: f {ef} R {er}°");
        }
        println!(
            "tsai (f rel, R deg) worst over seeds: ef {:.4}, er {:.4}",
            worst[0], worst[1]
        );
    }

    #[test]
    fn tsai_degenerate_inputs() {
        let (cam, p3, p2) = planar_scene(3, 10, 0.0);
        let pp = Point2::new(cam.intrinsics.u0, cam.intrinsics.v0);
        assert!(matches!(
            tsai(&p3[..5], &p2[..5], pp),
            Err(VisionError::TooFewPoints { .. })
        ));
        let mut off = p3.clone();
        off[0].z = 0.5;
        assert!(matches!(
            tsai(&off, &p2, pp),
            Err(VisionError::InvalidInput(_))
        ));
        let line: Vec<_> = (0..8)
            .map(|i| Point3::new(i as f64 * 0.1, 0.0, 0.0))
            .collect();
        let lp: Vec<_> = line.iter().map(|p| cam.project(p).unwrap()).collect();
        assert!(tsai(&line, &lp, pp).is_err());
    }
}
