//! Calibration with respect to a set of 3D points by the direct linear transform (book §4.1)
//! with the normalization of the 2D and 3D points (book §4.2).

use nalgebra::{DMatrix, Matrix3x4, Point2, Point3};

use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::normalize::{normalize_2d, normalize_3d};
use crate::optimize::min_norm_on_sphere;

/// Minimum number of matches of the DLT (book §4.1.1).
pub const DLT_MIN_POINTS: usize = 6;

/// The camera P minimizing ‖AP‖ with ‖P‖ = 1 for the system of book eq. 4.2, without
/// normalization (the book's `calib_singlecam`). Prefer [`dlt`].
pub fn dlt_unnormalized(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
) -> Result<Matrix3x4<f64>> {
    check_pairs(points3d.len(), points2d.len(), DLT_MIN_POINTS)?;
    let n = points3d.len();
    let mut a = DMatrix::zeros(2 * n, 12);
    for (i, (x3, x2)) in points3d.iter().zip(points2d).enumerate() {
        let xh = [x3.x, x3.y, x3.z, 1.0];
        for k in 0..4 {
            a[(2 * i, k)] = xh[k];
            a[(2 * i + 1, 4 + k)] = xh[k];
            a[(2 * i, 8 + k)] = -x2.x * xh[k];
            a[(2 * i + 1, 8 + k)] = -x2.y * xh[k];
        }
    }
    let nv = min_norm_on_sphere(&a)?;
    if nv.is_ambiguous(1e-10) {
        return Err(VisionError::Degenerate(
            "the DLT system has more than one solution".into(),
        ));
    }
    let p = Matrix3x4::from_row_slice(nv.x.as_slice());
    let m = p.fixed_view::<3, 3>(0, 0);
    if m.determinant().abs() <= 1e-12 * m.norm().powi(3) {
        return Err(VisionError::Degenerate(
            "the DLT camera has a singular left 3×3 block".into(),
        ));
    }
    Ok(p)
}

/// Check that 3D points are not all (nearly) on one plane or one line: the smallest eigenvalue
/// of their scatter matrix must not vanish relative to the largest.
pub fn check_not_coplanar(points3d: &[Point3<f64>]) -> Result<()> {
    let n = points3d.len() as f64;
    let c = points3d
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords)
        / n;
    let mut s = nalgebra::Matrix3::zeros();
    for p in points3d {
        let d = p.coords - c;
        s += d * d.transpose();
    }
    let ev = s.symmetric_eigen().eigenvalues;
    let (min, max) = (ev.min(), ev.max());
    if !(max > 0.0) || min <= 1e-10 * max {
        return Err(VisionError::Degenerate(
            "the 3D points are coplanar; use Tsai's planar calibration".into(),
        ));
    }
    Ok(())
}

/// The normalized DLT (book §4.2, the book's `calib_singlecam_dlt`): P = H⁻¹ P̃ T where P̃ is the
/// DLT of the normalized points. Needs ≥ 6 matches of non-coplanar 3D points.
pub fn dlt(points3d: &[Point3<f64>], points2d: &[Point2<f64>]) -> Result<Matrix3x4<f64>> {
    check_pairs(points3d.len(), points2d.len(), DLT_MIN_POINTS)?;
    check_finite("3D points", points3d.iter().flat_map(|p| p.coords.iter()))?;
    check_finite("2D points", points2d.iter().flat_map(|p| p.coords.iter()))?;
    check_not_coplanar(points3d)?;
    let (_, hinv, n2) = normalize_2d(points2d)?;
    let (t, n3) = normalize_3d(points3d)?;
    let pn = dlt_unnormalized(&n3, &n2)?;
    let p = hinv * pn * t;
    let norm = p.norm();
    Ok(p / norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::synthetic::{random_camera, random_points_in_front};
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    #[test]
    fn exact_data_gives_exact_camera() {
        let mut rng = Pcg64::seed_from_u64(3);
        let cam = random_camera(&mut rng);
        let pts = random_points_in_front(&cam, 20, &mut rng);
        let proj: Vec<_> = pts.iter().map(|p| cam.project(p).unwrap()).collect();
        let p = dlt(&pts, &proj).unwrap();
        let truth = cam.p_matrix();
        let truth = truth / truth.norm();
        let err = (p - truth).norm().min((p + truth).norm());
        assert!(err < 1e-9, "{err}");
        let pu = dlt_unnormalized(&pts, &proj).unwrap();
        let pu = pu / pu.norm();
        assert!((pu - truth).norm().min((pu + truth).norm()) < 1e-6);
    }

    #[test]
    fn degenerate_inputs() {
        let mut rng = Pcg64::seed_from_u64(4);
        let cam = random_camera(&mut rng);
        let pts = random_points_in_front(&cam, 10, &mut rng);
        let proj: Vec<_> = pts.iter().map(|p| cam.project(p).unwrap()).collect();
        assert!(matches!(
            dlt(&pts[..5], &proj[..5]),
            Err(VisionError::TooFewPoints { needed: 6, got: 5 })
        ));
        assert!(matches!(
            dlt(&pts[..7], &proj[..6]),
            Err(VisionError::LengthMismatch { .. })
        ));
        let planar: Vec<_> = pts.iter().map(|p| Point3::new(p.x, p.y, 2.0)).collect();
        let pproj: Vec<_> = planar.iter().map(|p| cam.project(p).unwrap()).collect();
        assert!(matches!(
            dlt(&planar, &pproj),
            Err(VisionError::Degenerate(_))
        ));
        let mut bad = proj.clone();
        bad[0].x = f64::NAN;
        assert!(matches!(dlt(&pts, &bad), Err(VisionError::InvalidInput(_))));
        let mut inf = pts.clone();
        inf[1].x = f64::INFINITY;
        assert!(matches!(
            dlt(&inf, &proj),
            Err(VisionError::InvalidInput(_))
        ));
    }
}
