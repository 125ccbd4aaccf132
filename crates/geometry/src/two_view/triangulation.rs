//! Three-dimensional reconstruction of a point from its projections (book §5.8.2,
//! `calib_get_3dpoint`): the linear method min ‖AX‖ on the unit sphere, for two or more views,
//! and an optional nonlinear refinement of the reprojection error by Levenberg–Marquardt.

use nalgebra::{DMatrix, Matrix3, Matrix3x4, Matrix4, Point2, Point3, Vector3, Vector4};

use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::optimize::{min_norm_on_sphere, LmOptions};

/// Linear triangulation from any number (≥ 2) of views (book §5.8.2 generalized): the rows
/// u P³ − P¹ and v P³ − P² of every view, each scaled to unit norm for conditioning.
/// A point whose homogeneous weight vanishes gives [`VisionError::PointsAtInfinity`].
pub fn triangulate_linear_n(
    cameras: &[Matrix3x4<f64>],
    points: &[Point2<f64>],
) -> Result<Point3<f64>> {
    check_pairs(cameras.len(), points.len(), 2)?;
    check_finite("2D points", points.iter().flat_map(|p| p.coords.iter()))?;
    let n = cameras.len();
    let mut a = DMatrix::zeros(2 * n, 4);
    for (i, (p, x)) in cameras.iter().zip(points).enumerate() {
        let r1 = p.row(2) * x.x - p.row(0);
        let r2 = p.row(2) * x.y - p.row(1);
        let (n1, n2) = (r1.norm(), r2.norm());
        if n1 == 0.0 || n2 == 0.0 {
            return Err(VisionError::Degenerate(
                "a camera matrix has a zero row combination".into(),
            ));
        }
        a.row_mut(2 * i).copy_from(&(r1 / n1));
        a.row_mut(2 * i + 1).copy_from(&(r2 / n2));
    }
    let nv = min_norm_on_sphere(&a)?;
    if nv.is_ambiguous(1e-12) {
        return Err(VisionError::ZeroBaseline);
    }
    let x = Vector4::new(nv.x[0], nv.x[1], nv.x[2], nv.x[3]);
    if x.w.abs() <= 1e-10 * x.xyz().norm() {
        return Err(VisionError::PointsAtInfinity);
    }
    Ok(Point3::from(x.xyz() / x.w))
}

/// Linear triangulation from two views (book §5.8.2).
pub fn triangulate_linear(
    pa: &Matrix3x4<f64>,
    pb: &Matrix3x4<f64>,
    xa: &Point2<f64>,
    xb: &Point2<f64>,
) -> Result<Point3<f64>> {
    if !(xa
        .coords
        .iter()
        .chain(xb.coords.iter())
        .all(|v| v.is_finite()))
    {
        return Err(VisionError::InvalidInput(
            "2D points contain a non-finite coordinate".into(),
        ));
    }
    // The 4×4 system of §5.8.2 with fixed-size matrices (this runs for every match of every
    // candidate pose).
    let mut a = Matrix4::zeros();
    for (k, (p, x)) in [(pa, xa), (pb, xb)].into_iter().enumerate() {
        let r1 = p.row(2) * x.x - p.row(0);
        let r2 = p.row(2) * x.y - p.row(1);
        let (n1, n2) = (r1.norm(), r2.norm());
        if !(n1 > 0.0 && n2 > 0.0) {
            return Err(VisionError::Degenerate(
                "a camera matrix has a zero row combination".into(),
            ));
        }
        a.row_mut(2 * k).copy_from(&(r1 / n1));
        a.row_mut(2 * k + 1).copy_from(&(r2 / n2));
    }
    let svd = a.svd(false, true);
    let vt = svd
        .v_t
        .ok_or_else(|| VisionError::Degenerate("SVD did not converge".into()))?;
    let sv = svd.singular_values;
    let mut order = [0usize, 1, 2, 3];
    order.sort_by(|&i, &j| sv[i].total_cmp(&sv[j]));
    if !sv.iter().all(|v| v.is_finite()) {
        return Err(VisionError::InvalidInput("non-finite camera matrix".into()));
    }
    if sv[order[1]] <= 1e-12 * sv[order[3]] {
        return Err(VisionError::ZeroBaseline);
    }
    let x: Vector4<f64> = vt.row(order[0]).transpose();
    if x.w.abs() <= 1e-10 * x.xyz().norm() {
        return Err(VisionError::PointsAtInfinity);
    }
    Ok(Point3::from(x.xyz() / x.w))
}

/// Refine a triangulated point by Levenberg–Marquardt on its reprojection error in all views
/// (the cameras fixed), starting from `initial`.
pub fn triangulate_nonlinear(
    cameras: &[Matrix3x4<f64>],
    points: &[Point2<f64>],
    initial: &Point3<f64>,
    options: &LmOptions,
) -> Result<Point3<f64>> {
    check_pairs(cameras.len(), points.len(), 2)?;
    // The generic solver's algorithm (book §3.3.2, Marquardt scaling, Nielsen damping) on
    // fixed-size 3×3 normal equations: this runs once per point.
    let eval = |x: &Vector3<f64>| -> Option<(f64, Matrix3<f64>, Vector3<f64>)> {
        let xh = Vector4::new(x.x, x.y, x.z, 1.0);
        let (mut cost, mut jtj, mut jtr) = (0.0, Matrix3::zeros(), Vector3::zeros());
        for (p, obs) in cameras.iter().zip(points) {
            let h = p * xh;
            if h.z.abs() <= 1e-14 * h.norm() || !h.z.is_finite() {
                return None;
            }
            let (u, v) = (h.x / h.z, h.y / h.z);
            let r = [u - obs.x, v - obs.y];
            let mut j = [Vector3::zeros(); 2];
            for k in 0..3 {
                j[0][k] = (p[(0, k)] - u * p[(2, k)]) / h.z;
                j[1][k] = (p[(1, k)] - v * p[(2, k)]) / h.z;
            }
            for c in 0..2 {
                cost += 0.5 * r[c] * r[c];
                jtj += j[c] * j[c].transpose();
                jtr += j[c] * r[c];
            }
        }
        cost.is_finite().then_some((cost, jtj, jtr))
    };
    let mut x = initial.coords;
    let Some((mut cost, mut jtj, mut jtr)) = eval(&x) else {
        return Err(VisionError::PointsAtInfinity);
    };
    let mut mu = options.initial_damping;
    let mut nu = 2.0;
    for _ in 0..options.max_iterations {
        if jtr.amax() <= options.gtol {
            break;
        }
        let mut a = jtj;
        let dmax = jtj.diagonal().amax();
        for k in 0..3 {
            a[(k, k)] += mu * jtj[(k, k)].max(1e-12 * dmax).max(1e-300);
        }
        let Some(h) = a.cholesky().map(|c| c.solve(&(-jtr))) else {
            mu *= nu;
            nu *= 2.0;
            continue;
        };
        if h.norm() <= options.xtol * (x.norm() + options.xtol) {
            break;
        }
        let predicted = -h.dot(&jtr) - 0.5 * h.dot(&(jtj * h));
        match eval(&(x + h)) {
            Some((c_new, jtj_new, jtr_new)) if predicted > 0.0 && c_new < cost => {
                let rho = (cost - c_new) / predicted;
                let small = cost - c_new <= options.ftol * c_new.max(1e-300);
                x += h;
                (cost, jtj, jtr) = (c_new, jtj_new, jtr_new);
                mu *= (1.0 / 3.0f64).max(1.0 - (2.0 * rho - 1.0).powi(3));
                nu = 2.0;
                if small {
                    break;
                }
            }
            _ => {
                mu *= nu;
                nu *= 2.0;
                if mu > 1e32 {
                    break;
                }
            }
        }
    }
    Ok(Point3::from(x))
}

/// Linear triangulation followed by the nonlinear refinement.
pub fn triangulate(cameras: &[Matrix3x4<f64>], points: &[Point2<f64>]) -> Result<Point3<f64>> {
    let x0 = triangulate_linear_n(cameras, points)?;
    let opts = LmOptions {
        max_iterations: 20,
        ..LmOptions::default()
    };
    triangulate_nonlinear(cameras, points, &x0, &opts)
}

/// The angle in radians between the rays from two camera centres to a point (the parallax).
pub fn parallax_angle(ca: &Point3<f64>, cb: &Point3<f64>, x: &Point3<f64>) -> f64 {
    let (da, db) = (x - ca, x - cb);
    let c = da.dot(&db) / (da.norm() * db.norm());
    c.clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimize::{levenberg_marquardt, LeastSquaresProblem};
    use nalgebra::DVector;

    /// The same problem for the generic solver, as a reference.
    struct PointProblem<'a> {
        cameras: &'a [Matrix3x4<f64>],
        points: &'a [Point2<f64>],
    }

    impl LeastSquaresProblem for PointProblem<'_> {
        fn residuals(&self, x: &DVector<f64>) -> DVector<f64> {
            let xh = Vector4::new(x[0], x[1], x[2], 1.0);
            let mut r = DVector::zeros(2 * self.cameras.len());
            for (i, (p, obs)) in self.cameras.iter().zip(self.points).enumerate() {
                let h = p * xh;
                if h.z.abs() <= 1e-14 * h.norm() {
                    r[2 * i] = f64::INFINITY;
                    r[2 * i + 1] = f64::INFINITY;
                } else {
                    r[2 * i] = h.x / h.z - obs.x;
                    r[2 * i + 1] = h.y / h.z - obs.y;
                }
            }
            r
        }

        fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
            let xh = Vector4::new(x[0], x[1], x[2], 1.0);
            let mut j = DMatrix::zeros(2 * self.cameras.len(), 3);
            for (i, p) in self.cameras.iter().enumerate() {
                let h = p * xh;
                let (u, v) = (h.x / h.z, h.y / h.z);
                for k in 0..3 {
                    j[(2 * i, k)] = (p[(0, k)] - u * p[(2, k)]) / h.z;
                    j[(2 * i + 1, k)] = (p[(1, k)] - v * p[(2, k)]) / h.z;
                }
            }
            Some(j)
        }
    }
    use crate::two_view::tests::two_view_scene;

    #[test]
    fn exact_and_refined_triangulation() {
        let s = two_view_scene(4, 20, 0.0, 0.0);
        let (pa, pb) = (s.camera_a().p_matrix(), s.camera_b().p_matrix());
        for i in 0..20 {
            let x = triangulate_linear(&pa, &pb, &s.a[i], &s.b[i]).unwrap();
            assert!((x - s.points[i]).norm() < 1e-8);
        }
        // With noise the refinement lowers the reprojection error.
        let s = two_view_scene(4, 20, 1.0, 0.0);
        let cams = [pa, pb];
        for i in 0..20 {
            let obs = [s.a[i], s.b[i]];
            let lin = triangulate_linear_n(&cams, &obs).unwrap();
            let nl = triangulate(&cams, &obs).unwrap();
            let pb_ = PointProblem {
                cameras: &cams,
                points: &obs,
            };
            let c_lin = pb_
                .residuals(&DVector::from_column_slice(lin.coords.as_slice()))
                .norm();
            let c_nl = pb_
                .residuals(&DVector::from_column_slice(nl.coords.as_slice()))
                .norm();
            assert!(c_nl <= c_lin + 1e-12);
            // The fixed-size solver reaches the generic solver's minimum.
            let x0 = DVector::from_column_slice(lin.coords.as_slice());
            let (g, _) = levenberg_marquardt(&pb_, x0, &LmOptions::default());
            assert!((nl.coords - Vector3::new(g[0], g[1], g[2])).norm() < 1e-6 * nl.coords.norm());
        }
    }

    #[test]
    fn zero_baseline_and_infinity() {
        let s = two_view_scene(5, 5, 0.0, 0.0);
        let pa = s.camera_a().p_matrix();
        // Same camera twice: rays coincide.
        assert!(triangulate_linear(&pa, &pa, &s.a[0], &s.a[0]).is_err());
        // Parallel rays from distinct centres: a point at infinity.
        let mut shifted = s.camera_a();
        shifted.pose.t = nalgebra::Vector3::new(1.0, 0.0, 0.0);
        let e = triangulate_linear(&pa, &shifted.p_matrix(), &s.a[0], &s.a[0]);
        assert!(matches!(e, Err(VisionError::PointsAtInfinity)), "{e:?}");
        assert!(matches!(
            triangulate_linear_n(&[pa], &[s.a[0]]),
            Err(VisionError::TooFewPoints { .. })
        ));
    }
}
