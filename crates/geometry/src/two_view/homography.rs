//! Plane-induced homographies x_b ~ H x_a by the normalized 4-point DLT. Used to detect the
//! configurations where the fundamental matrix is not determined: a pure rotation (zero baseline,
//! H = K_b R K_a⁻¹) and a planar scene (Hartley & Zisserman §4.1, §11.9).

use nalgebra::{DMatrix, Matrix3, Point2};

use crate::error::{check_pairs, Result, VisionError};
use crate::normalize::normalize_2d;
use crate::optimize::min_norm_on_sphere;
use crate::ransac::Estimator;

/// The normalized DLT homography of ≥ 4 matches, ‖H‖ = 1.
pub fn homography_dlt(a: &[Point2<f64>], b: &[Point2<f64>]) -> Result<Matrix3<f64>> {
    check_pairs(a.len(), b.len(), 4)?;
    let (ha, _, na) = normalize_2d(a)?;
    let (_, hb_inv, nb) = normalize_2d(b)?;
    let n = a.len();
    let mut m = DMatrix::zeros(2 * n, 9);
    for i in 0..n {
        let (x, y, u, v) = (na[i].x, na[i].y, nb[i].x, nb[i].y);
        let r1 = [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u];
        let r2 = [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v];
        for k in 0..9 {
            m[(2 * i, k)] = r1[k];
            m[(2 * i + 1, k)] = r2[k];
        }
    }
    let nv = min_norm_on_sphere(&m)?;
    if nv.is_ambiguous(1e-10) {
        return Err(VisionError::Degenerate("homography not determined".into()));
    }
    let h = hb_inv * Matrix3::from_row_slice(nv.x.as_slice()) * ha;
    Ok(h / h.norm())
}

/// Transfer error ‖x_b − H x_a‖ in pixels.
pub fn transfer_error(h: &Matrix3<f64>, xa: &Point2<f64>, xb: &Point2<f64>) -> f64 {
    let p = h * xa.to_homogeneous();
    if p.z.abs() <= 1e-14 * p.norm() {
        return f64::INFINITY;
    }
    ((p.x / p.z - xb.x).powi(2) + (p.y / p.z - xb.y).powi(2)).sqrt()
}

/// The 4-point homography as a RANSAC estimator.
#[derive(Clone, Copy, Debug, Default)]
pub struct HomographyEstimator;

impl Estimator for HomographyEstimator {
    type Datum = (Point2<f64>, Point2<f64>);
    type Model = Matrix3<f64>;
    const MIN_SAMPLES: usize = 4;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model> {
        let a: Vec<_> = sample.iter().map(|&i| data[i].0).collect();
        let b: Vec<_> = sample.iter().map(|&i| data[i].1).collect();
        homography_dlt(&a, &b).into_iter().collect()
    }

    fn residual(&self, h: &Self::Model, d: &Self::Datum) -> f64 {
        transfer_error(h, &d.0, &d.1)
    }
}
