//! Three-dimensional reconstruction of a point from its projections (book §5.8.2,
//! `calib_get_3dpoint`): the linear method min ‖AX‖ on the unit sphere, for two or more views,
//! and an optional nonlinear refinement of the reprojection error by Levenberg–Marquardt.

use nalgebra::{DMatrix, DVector, Matrix3x4, Point2, Point3, Vector4};

use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::optimize::{levenberg_marquardt, min_norm_on_sphere, LeastSquaresProblem, LmOptions};

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
    triangulate_linear_n(&[*pa, *pb], &[*xa, *xb])
}

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

/// Refine a triangulated point by Levenberg–Marquardt on its reprojection error in all views
/// (the cameras fixed), starting from `initial`.
pub fn triangulate_nonlinear(
    cameras: &[Matrix3x4<f64>],
    points: &[Point2<f64>],
    initial: &Point3<f64>,
    options: &LmOptions,
) -> Result<Point3<f64>> {
    check_pairs(cameras.len(), points.len(), 2)?;
    let problem = PointProblem { cameras, points };
    let x0 = DVector::from_column_slice(initial.coords.as_slice());
    if problem.residuals(&x0).iter().any(|v| !v.is_finite()) {
        return Err(VisionError::PointsAtInfinity);
    }
    let (x, _) = levenberg_marquardt(&problem, x0, options);
    Ok(Point3::new(x[0], x[1], x[2]))
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
