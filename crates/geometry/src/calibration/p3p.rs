//! Pose of a calibrated camera from three points (P3P), after Persson & Nordberg, "Lambda Twist:
//! an accurate fast robust perspective three point (P3P) solver" (ECCV 2018), and
//! [`resect_p3p`]: RANSAC on it with a known K, then Levenberg–Marquardt on the pose.
//!
//! The book resects every frame by the 6-point DLT (§4.1, §7.3), which estimates K too and is
//! degenerate when the points are coplanar — a floor, a wall. With K known, three points fix
//! the pose whatever the structure.
//!
//! The three distance equations |λᵢyᵢ − λⱼyⱼ|² = |xᵢ − xⱼ|² are quadratic forms λᵀMᵢⱼλ = aᵢⱼ;
//! two homogeneous combinations D₁, D₂ share the solutions, and a root γ of the cubic
//! det(D₁ + γD₂) = 0 makes D₀ = D₁ + γD₂ degenerate, so λᵀD₀λ = 0 splits into two planes
//! through the origin. On each plane the equations reduce to a quadratic in one ratio. Each
//! solution's λ is refined by Gauss–Newton on the three equations, and the pose follows in
//! closed form.

use nalgebra::{Matrix3, Point2, Point3, SymmetricEigen, Vector3};
use rand::Rng;

use super::resection::{refine_and_remark, PoseEstimate};
use super::restricted::{refine_camera, IntrinsicsModel};
use crate::camera::{Camera, Intrinsics, Pose};
use crate::error::{check_pairs, Result};
use crate::optimize::LmOptions;
use crate::ransac::{ransac, Estimator, RansacParams};

/// Every pose (up to four) with `yᵢ ∝ R xᵢ + t` and the points in front, for three world
/// points `x` and their unit bearing vectors `y` in the camera's frame.
pub fn p3p(x: &[Vector3<f64>; 3], y: &[Vector3<f64>; 3]) -> Vec<Pose> {
    if !x.iter().chain(y).all(|v| v.iter().all(|c| c.is_finite())) {
        return Vec::new();
    }
    let y = y.map(|v| v.normalize());
    let a12 = (x[0] - x[1]).norm_squared();
    let a13 = (x[0] - x[2]).norm_squared();
    let a23 = (x[1] - x[2]).norm_squared();
    let scale = a12.max(a13).max(a23);
    if !(scale > 0.0) || a12.min(a13).min(a23) < 1e-18 * scale {
        return Vec::new();
    }
    let b12 = -y[0].dot(&y[1]);
    let b13 = -y[0].dot(&y[2]);
    let b23 = -y[1].dot(&y[2]);
    let m12 = Matrix3::new(1.0, b12, 0.0, b12, 1.0, 0.0, 0.0, 0.0, 0.0);
    let m13 = Matrix3::new(1.0, 0.0, b13, 0.0, 0.0, 0.0, b13, 0.0, 1.0);
    let m23 = Matrix3::new(0.0, 0.0, 0.0, 0.0, 1.0, b23, 0.0, b23, 1.0);
    let d1 = m12 * a23 - m23 * a12;
    let d2 = m13 * a23 - m23 * a13;
    // det(D1 + γD2) = det D1 + γ tr(adj(D1)D2) + γ² tr(adj(D2)D1) + γ³ det D2.
    let c3 = d2.determinant();
    let c2 = (adjugate(&d2) * d1).trace();
    let c1 = (adjugate(&d1) * d2).trace();
    let c0 = d1.determinant();
    let equations = |l: &Vector3<f64>| -> Vector3<f64> {
        Vector3::new(
            l.dot(&(m12 * l)) - a12,
            l.dot(&(m13 * l)) - a13,
            l.dot(&(m23 * l)) - a23,
        )
    };
    let mut lambdas: Vec<Vector3<f64>> = Vec::new();
    for gamma in real_cubic_roots(c3, c2, c1, c0) {
        let d0 = d1 + d2 * gamma;
        let eig = SymmetricEigen::new(d0);
        // The two eigenvalues away from zero, largest magnitude first.
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&i, &j| {
            eig.eigenvalues[j]
                .abs()
                .total_cmp(&eig.eigenvalues[i].abs())
        });
        let (sa, sb) = (eig.eigenvalues[idx[0]], eig.eigenvalues[idx[1]]);
        if sa * sb >= 0.0 {
            continue;
        }
        let s = (-sb / sa).sqrt();
        let (ea, eb) = (
            eig.eigenvectors.column(idx[0]).into_owned(),
            eig.eigenvectors.column(idx[1]).into_owned(),
        );
        for sign in [1.0, -1.0] {
            // λ on the plane wᵀλ = 0.
            let w = ea - eb * (sign * s);
            let u = w.cross(&eigen_helper(&w)).normalize();
            let v = w.cross(&u).normalize();
            // λ = αu + βv: a13·eq12 − a12·eq13 is homogeneous in (α, β).
            let q = |m: &Matrix3<f64>| (u.dot(&(m * u)), 2.0 * u.dot(&(m * v)), v.dot(&(m * v)));
            let (p12, p13) = (q(&m12), q(&m13));
            let (qa, qb, qc) = (
                a13 * p12.0 - a12 * p13.0,
                a13 * p12.1 - a12 * p13.1,
                a13 * p12.2 - a12 * p13.2,
            );
            let mut dirs = Vec::new();
            if qa.abs() >= qc.abs() {
                for t in real_quadratic_roots(qa, qb, qc) {
                    dirs.push(u * t + v);
                }
            } else {
                for t in real_quadratic_roots(qc, qb, qa) {
                    dirs.push(u + v * t);
                }
            }
            for d in dirs {
                let g = d.dot(&(m12 * d));
                if !(g > 0.0) {
                    continue;
                }
                let mut l = d * (a12 / g).sqrt();
                if l.sum() < 0.0 {
                    l = -l;
                }
                if l.iter().any(|&c| c <= 0.0) {
                    continue;
                }
                let l = refine_lambda(l, &equations, b12, b13, b23);
                let r = equations(&l);
                if !(r.amax() <= 1e-6 * scale) || l.iter().any(|&c| !(c > 0.0)) {
                    continue;
                }
                if lambdas.iter().all(|o| (o - l).amax() > 1e-9 * l.amax()) {
                    lambdas.push(l);
                }
            }
        }
    }
    lambdas
        .into_iter()
        .filter_map(|l| pose_of(x, &y, &l))
        .collect()
}

/// Gauss–Newton on the three distance equations (their Jacobian in closed form).
fn refine_lambda(
    mut l: Vector3<f64>,
    equations: &dyn Fn(&Vector3<f64>) -> Vector3<f64>,
    b12: f64,
    b13: f64,
    b23: f64,
) -> Vector3<f64> {
    for _ in 0..5 {
        let r = equations(&l);
        let j = Matrix3::new(
            2.0 * (l[0] + b12 * l[1]),
            2.0 * (l[1] + b12 * l[0]),
            0.0,
            2.0 * (l[0] + b13 * l[2]),
            0.0,
            2.0 * (l[2] + b13 * l[0]),
            0.0,
            2.0 * (l[1] + b23 * l[2]),
            2.0 * (l[2] + b23 * l[1]),
        );
        let Some(step) = j.lu().solve(&r) else {
            break;
        };
        let next = l - step;
        if !next.iter().all(|c| c.is_finite()) || equations(&next).amax() >= r.amax() {
            break;
        }
        l = next;
    }
    l
}

/// The pose taking the world points to λᵢyᵢ (closed form from three points, projected onto
/// the rotations).
fn pose_of(x: &[Vector3<f64>; 3], y: &[Vector3<f64>; 3], l: &Vector3<f64>) -> Option<Pose> {
    let p = [y[0] * l[0], y[1] * l[1], y[2] * l[2]];
    let (x1, x2) = (x[0] - x[1], x[0] - x[2]);
    let (p1, p2) = (p[0] - p[1], p[0] - p[2]);
    let xm = Matrix3::from_columns(&[x1, x2, x1.cross(&x2)]);
    let pm = Matrix3::from_columns(&[p1, p2, p1.cross(&p2)]);
    let r = pm * xm.try_inverse()?;
    if !r.iter().all(|c| c.is_finite()) {
        return None;
    }
    let r = crate::rotation::nearest_rotation(&r);
    if !(r.determinant() > 0.0) {
        return None;
    }
    let t = p[0] - r * x[0];
    Some(Pose::new(r, t))
}

/// A vector not parallel to `w`.
fn eigen_helper(w: &Vector3<f64>) -> Vector3<f64> {
    let a = w.map(f64::abs);
    if a.x <= a.y && a.x <= a.z {
        Vector3::x()
    } else if a.y <= a.z {
        Vector3::y()
    } else {
        Vector3::z()
    }
}

/// The adjugate (transposed cofactors) of a 3×3 matrix.
fn adjugate(m: &Matrix3<f64>) -> Matrix3<f64> {
    let c = |r0: usize, r1: usize, c0: usize, c1: usize| {
        m[(r0, c0)] * m[(r1, c1)] - m[(r0, c1)] * m[(r1, c0)]
    };
    Matrix3::new(
        c(1, 2, 1, 2),
        -c(0, 2, 1, 2),
        c(0, 1, 1, 2),
        -c(1, 2, 0, 2),
        c(0, 2, 0, 2),
        -c(0, 1, 0, 2),
        c(1, 2, 0, 1),
        -c(0, 2, 0, 1),
        c(0, 1, 0, 1),
    )
}

/// Real roots of a t² + b t + c (a ≠ 0 expected; a linear equation when a is 0).
fn real_quadratic_roots(a: f64, b: f64, c: f64) -> Vec<f64> {
    if a == 0.0 {
        return if b != 0.0 { vec![-c / b] } else { Vec::new() };
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        // A tangent double root lost to rounding is kept.
        if disc > -1e-12 * b * b {
            return vec![-b / (2.0 * a)];
        }
        return Vec::new();
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        return vec![0.0];
    }
    vec![q / a, c / q]
}

/// Real roots of c3 t³ + c2 t² + c1 t + c0, each polished by Newton steps.
fn real_cubic_roots(c3: f64, c2: f64, c1: f64, c0: f64) -> Vec<f64> {
    let m = c3.abs().max(c2.abs()).max(c1.abs()).max(c0.abs());
    if !(m > 0.0) || !m.is_finite() {
        return Vec::new();
    }
    if c3.abs() < 1e-12 * m {
        return real_quadratic_roots(c2, c1, c0);
    }
    let (a, b, c) = (c2 / c3, c1 / c3, c0 / c3);
    // Depressed cubic t = s − a/3: s³ + p s + q = 0.
    let p = b - a * a / 3.0;
    let q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
    let disc = q * q / 4.0 + p * p * p / 27.0;
    let mut roots = if disc > 0.0 {
        let sq = disc.sqrt();
        vec![(-q / 2.0 + sq).cbrt() + (-q / 2.0 - sq).cbrt()]
    } else {
        let r = (-p / 3.0).max(0.0).sqrt();
        let phi = if r > 0.0 {
            (-q / (2.0 * r * r * r)).clamp(-1.0, 1.0).acos()
        } else {
            0.0
        };
        (0..3)
            .map(|k| 2.0 * r * ((phi + 2.0 * std::f64::consts::PI * k as f64) / 3.0).cos())
            .collect()
    };
    for s in &mut roots {
        *s -= a / 3.0;
        for _ in 0..3 {
            let f = ((*s + a) * *s + b) * *s + c;
            let df = (3.0 * *s + 2.0 * a) * *s + b;
            if df == 0.0 {
                break;
            }
            let next = *s - f / df;
            if next.is_finite() {
                *s = next;
            }
        }
    }
    roots
}

/// P3P with a known K as a RANSAC estimator over 3D↔2D matches (pixels); the residual is the
/// reprojection error in pixels (∞ behind the camera), and the local optimization refines the
/// pose on the inliers.
pub struct P3pEstimator {
    /// The known intrinsics (pinhole).
    pub k: Intrinsics,
    k_inv: Matrix3<f64>,
}

impl P3pEstimator {
    /// The estimator for cameras with intrinsics `k`.
    pub fn new(k: &Intrinsics) -> Self {
        P3pEstimator {
            k: k.clone(),
            k_inv: k.k_inv(),
        }
    }
}

impl Estimator for P3pEstimator {
    type Datum = (Point3<f64>, Point2<f64>);
    type Model = Pose;
    const MIN_SAMPLES: usize = 3;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Pose> {
        let x = [0, 1, 2].map(|i| data[sample[i]].0.coords);
        let y = [0, 1, 2].map(|i| (self.k_inv * data[sample[i]].1.to_homogeneous()).normalize());
        p3p(&x, &y)
    }

    fn residual(&self, pose: &Pose, d: &Self::Datum) -> f64 {
        let c = pose.r * d.0.coords + pose.t;
        if !(c.z > 1e-12) {
            return f64::INFINITY;
        }
        let k = &self.k;
        let (u, v) = (c.x / c.z, c.y / c.z);
        ((k.f1 * u + k.s * v + k.u0 - d.1.x).powi(2) + (k.f2 * v + k.v0 - d.1.y).powi(2)).sqrt()
    }

    fn refit(&self, data: &[Self::Datum], inliers: &[usize], pose: &Pose) -> Option<Pose> {
        if inliers.len() < 4 {
            return None;
        }
        let p3: Vec<_> = inliers.iter().map(|&i| data[i].0).collect();
        let p2: Vec<_> = inliers.iter().map(|&i| data[i].1).collect();
        let cam = Camera {
            intrinsics: self.k.clone(),
            pose: pose.clone(),
        };
        let lm = LmOptions {
            max_iterations: 10,
            ..LmOptions::default()
        };
        refine_camera(&p3, &p2, &cam, IntrinsicsModel::Fixed(self.k.clone()), &lm)
            .ok()
            .map(|(c, _)| c.pose)
    }
}

/// Pose of a camera with known (pinhole) K from 3D↔2D matches with outliers: RANSAC on
/// [`p3p`] with local optimization, then Levenberg–Marquardt on the pose over the inliers,
/// re-marked at `params.threshold` pixels (twice at most). Sound on coplanar points.
pub fn resect_p3p<R: Rng + ?Sized>(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    k: &Intrinsics,
    params: &RansacParams,
    rng: &mut R,
) -> Result<PoseEstimate> {
    k.validate()?;
    check_pairs(points3d.len(), points2d.len(), 4)?;
    let data: Vec<_> = points3d
        .iter()
        .copied()
        .zip(points2d.iter().copied())
        .collect();
    let est = P3pEstimator::new(k);
    let res = ransac(&est, &data, params, rng)?;
    let camera = Camera {
        intrinsics: k.clone(),
        pose: res.model,
    };
    let mut est = refine_and_remark(points3d, points2d, camera, res.inliers, params.threshold, 4)?;
    est.iterations = res.iterations;
    Ok(est)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::{axis_angle_to_r, rotation_angle_between};
    use crate::synthetic::gaussian;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    fn random_pose(rng: &mut Pcg64) -> Pose {
        let r =
            axis_angle_to_r(&Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)).scale(0.8));
        Pose::new(
            r,
            Vector3::new(gaussian(rng), gaussian(rng), 6.0 + gaussian(rng)),
        )
    }

    /// Points in front of the camera (in its frame, mapped back to the world); `planar`: on a
    /// plane through the scene.
    fn points(rng: &mut Pcg64, pose: &Pose, n: usize, planar: bool) -> Vec<Vector3<f64>> {
        let inv = pose.inverse();
        (0..n)
            .map(|_| {
                let (x, y) = (rng.random_range(-2.0..2.0), rng.random_range(-1.5..1.5));
                let z = if planar {
                    6.0 + 0.4 * x - 0.3 * y
                } else {
                    rng.random_range(4.0..9.0)
                };
                inv.r * Vector3::new(x, y, z) + inv.t
            })
            .collect()
    }

    #[test]
    fn exact_at_zero_noise_general_and_planar() {
        let mut rng = Pcg64::seed_from_u64(9);
        let (mut found, mut total) = (0, 0);
        for planar in [false, true] {
            for _ in 0..300 {
                let pose = random_pose(&mut rng);
                let x = points(&mut rng, &pose, 3, planar);
                let x = [x[0], x[1], x[2]];
                let y = x.map(|p| (pose.r * p + pose.t).normalize());
                let sols = p3p(&x, &y);
                assert!(sols.len() <= 4);
                for s in &sols {
                    for i in 0..3 {
                        let c = s.r * x[i] + s.t;
                        assert!(
                            (c.normalize() - y[i]).norm() < 1e-7,
                            "{}",
                            (c.normalize() - y[i]).norm()
                        );
                    }
                }
                total += 1;
                let best = sols
                    .iter()
                    .map(|s| rotation_angle_between(&s.r, &pose.r) + (s.t - pose.t).norm())
                    .fold(f64::INFINITY, f64::min);
                if best < 1e-8 {
                    found += 1;
                }
            }
        }
        assert_eq!(found, total);
    }

    #[test]
    fn degenerate_triples_are_refused() {
        let p = Vector3::new(0.0, 0.0, 5.0);
        let y = Vector3::z();
        assert!(p3p(&[p, p, Vector3::new(1.0, 0.0, 5.0)], &[y, y, y]).is_empty());
        let nan = Vector3::new(f64::NAN, 0.0, 1.0);
        assert!(p3p(&[nan, p, p], &[y, y, y]).is_empty());
    }

    #[test]
    fn resection_with_outliers_on_a_plane() {
        let mut rng = Pcg64::seed_from_u64(10);
        let k = Intrinsics::new(900.0, 900.0, 480.0, 270.0);
        for planar in [true, false] {
            let pose = random_pose(&mut rng);
            let x = points(&mut rng, &pose, 200, planar);
            let mut outlier = vec![false; x.len()];
            let p3: Vec<Point3<f64>> = x.iter().map(|p| Point3::from(*p)).collect();
            let p2: Vec<Point2<f64>> = x
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let c = pose.r * p + pose.t;
                    let mut q = Point2::new(
                        900.0 * c.x / c.z + 480.0 + 0.3 * gaussian(&mut rng),
                        900.0 * c.y / c.z + 270.0 + 0.3 * gaussian(&mut rng),
                    );
                    if i % 4 == 0 {
                        outlier[i] = true;
                        q.x += 30.0 + 50.0 * rng.random::<f64>();
                    }
                    q
                })
                .collect();
            let est =
                resect_p3p(&p3, &p2, &k, &RansacParams::with_threshold(2.0), &mut rng).unwrap();
            let er = rotation_angle_between(&est.camera.pose.r, &pose.r).to_degrees();
            assert!(er < 0.05, "planar {planar}: {er}°");
            assert!(est.inliers.iter().zip(&outlier).all(|(i, o)| !(*i && *o)));
            assert!(est.num_inliers >= 140, "{}", est.num_inliers);
        }
    }
}
