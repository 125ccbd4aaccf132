//! The fundamental matrix (book §5.2–5.7): the 8-point algorithm, the rank-2 enforcement of
//! Theorem 5.2, the normalized 8-point algorithm (§5.7, Hartley 1997), epipolar residuals and a
//! RANSAC estimator.
//!
//! Convention: for a match (x_a, x_b) between views A and B, x_bᵀ F x_a = 0 (the book's
//! `calib_fmatrix_make(f, b, a)`): F maps a point of A to its epipolar line in B.

use nalgebra::{DMatrix, Matrix3, Point2, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::normalize::normalize_2d;
use crate::optimize::min_norm_on_sphere;
use crate::ransac::Estimator;

/// Minimum number of matches of the 8-point algorithm.
pub const EIGHT_POINT_MIN: usize = 8;

/// The 8-point algorithm without normalization (book §5.6, `calib_fmatrix_make`): min ‖Af‖ over
/// ‖f‖ = 1, rank not enforced.
pub fn fundamental_8point_unnormalized(
    a: &[Point2<f64>],
    b: &[Point2<f64>],
) -> Result<Matrix3<f64>> {
    check_pairs(a.len(), b.len(), EIGHT_POINT_MIN)?;
    let n = a.len();
    let mut m = DMatrix::zeros(n, 9);
    for i in 0..n {
        let (xa, ya, xb, yb) = (a[i].x, a[i].y, b[i].x, b[i].y);
        let row = [xb * xa, xb * ya, xb, yb * xa, yb * ya, yb, xa, ya, 1.0];
        for (k, v) in row.iter().enumerate() {
            m[(i, k)] = *v;
        }
    }
    let nv = min_norm_on_sphere(&m)?;
    if nv.is_ambiguous(1e-10) {
        return Err(VisionError::Degenerate(
            "the 8-point system has more than one solution (pure rotation, planar scene or repeated points)".into(),
        ));
    }
    Ok(Matrix3::from_row_slice(nv.x.as_slice()))
}

/// The closest rank-2 matrix in the Frobenius norm (book Theorem 5.2): U diag(r, s, 0) Vᵀ.
pub fn enforce_rank2(f: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = f.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => {
            let mut s = svd.singular_values;
            let (imin, _) = s.argmin();
            s[imin] = 0.0;
            u * Matrix3::from_diagonal(&s) * vt
        }
        _ => *f,
    }
}

/// The normalized 8-point algorithm (book §5.7, `calib_fmatrix_dlt`): F = H_bᵀ F' H_a with the
/// rank-2 constraint enforced on F' before denormalization; ‖F‖ = 1.
pub fn fundamental_8point(a: &[Point2<f64>], b: &[Point2<f64>]) -> Result<Matrix3<f64>> {
    check_pairs(a.len(), b.len(), EIGHT_POINT_MIN)?;
    check_finite("points", a.iter().chain(b).flat_map(|p| p.coords.iter()))?;
    let (ha, _, na) = normalize_2d(a)?;
    let (hb, _, nb) = normalize_2d(b)?;
    let fp = enforce_rank2(&fundamental_8point_unnormalized(&na, &nb)?);
    let f = hb.transpose() * fp * ha;
    let norm = f.norm();
    if !(norm > 0.0) {
        return Err(VisionError::Degenerate("zero fundamental matrix".into()));
    }
    Ok(f / norm)
}

/// The algebraic epipolar error |x_bᵀ F x_a| (the book's RANSAC residual; depends on the scale
/// of F and of the pixel coordinates).
pub fn algebraic_error(f: &Matrix3<f64>, xa: &Point2<f64>, xb: &Point2<f64>) -> f64 {
    xb.to_homogeneous().dot(&(f * xa.to_homogeneous())).abs()
}

/// The Sampson distance in pixels: the first-order approximation of the distance of (x_a, x_b)
/// to the nearest match that satisfies the epipolar constraint exactly (Hartley & Zisserman
/// eq. 11.9), |x_bᵀFx_a| / √((Fx_a)₁² + (Fx_a)₂² + (Fᵀx_b)₁² + (Fᵀx_b)₂²).
pub fn sampson_distance(f: &Matrix3<f64>, xa: &Point2<f64>, xb: &Point2<f64>) -> f64 {
    let ha: Vector3<f64> = xa.to_homogeneous();
    let hb: Vector3<f64> = xb.to_homogeneous();
    let fa = f * ha;
    let fb = f.transpose() * hb;
    let num = hb.dot(&fa);
    let den = fa.x * fa.x + fa.y * fa.y + fb.x * fb.x + fb.y * fb.y;
    if den <= 0.0 {
        return f64::INFINITY;
    }
    num.abs() / den.sqrt()
}

/// The residual [`FundamentalEstimator`] thresholds.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, vfxgraph_params::Choice,
)]
#[serde(rename_all = "lowercase")]
pub enum EpipolarResidual {
    /// Sampson distance in pixels (default).
    #[default]
    Sampson,
    /// The book's algebraic error |x_bᵀFx_a| with ‖F‖ = 1 (computed on whatever coordinates the
    /// data are in; [`super::reconstruct_two_view`] passes normalized points).
    Algebraic,
}

/// The normalized 8-point algorithm as a RANSAC estimator over matches (x_a, x_b).
#[derive(Clone, Copy, Debug, Default)]
pub struct FundamentalEstimator {
    /// The residual to threshold.
    pub residual: EpipolarResidual,
}

impl Estimator for FundamentalEstimator {
    type Datum = (Point2<f64>, Point2<f64>);
    type Model = Matrix3<f64>;
    const MIN_SAMPLES: usize = EIGHT_POINT_MIN;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model> {
        let a: Vec<_> = sample.iter().map(|&i| data[i].0).collect();
        let b: Vec<_> = sample.iter().map(|&i| data[i].1).collect();
        fundamental_8point(&a, &b).into_iter().collect()
    }

    fn residual(&self, f: &Self::Model, d: &Self::Datum) -> f64 {
        match self.residual {
            EpipolarResidual::Sampson => sampson_distance(f, &d.0, &d.1),
            EpipolarResidual::Algebraic => algebraic_error(f, &d.0, &d.1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::two_view::tests::two_view_scene;

    #[test]
    fn eight_point_on_exact_data() {
        let s = two_view_scene(1, 50, 0.0, 0.0);
        let f = fundamental_8point(&s.a, &s.b).unwrap();
        let truth = s.fundamental();
        let truth = truth / truth.norm();
        assert!((f - truth).norm().min((f + truth).norm()) < 1e-8);
        assert!(f.determinant().abs() < 1e-12);
        for (xa, xb) in s.a.iter().zip(&s.b) {
            assert!(sampson_distance(&f, xa, xb) < 1e-6);
        }
    }

    #[test]
    fn eight_point_degenerate_inputs() {
        let s = two_view_scene(2, 20, 0.0, 0.0);
        assert!(matches!(
            fundamental_8point(&s.a[..7], &s.b[..7]),
            Err(VisionError::TooFewPoints { needed: 8, got: 7 })
        ));
        assert!(matches!(
            fundamental_8point(&s.a[..9], &s.b[..8]),
            Err(VisionError::LengthMismatch { .. })
        ));
        let same = vec![s.a[0]; 10];
        assert!(fundamental_8point(&same, &s.b[..10]).is_err());
    }
}
