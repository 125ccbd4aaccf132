//! Linear least squares (book §3.2) and min ‖Ax‖ over the unit sphere (book §3.4, Theorem 3.2).

use nalgebra::{DMatrix, DVector};

use crate::error::{Result, VisionError};

/// Solve min ‖Ax − b‖² (book §3.2). The book solves the normal equations AᵀAx = Aᵀb; this uses
/// a QR factorization of A, which gives the same minimizer with the conditioning of A instead
/// of AᵀA. A rank-deficient A gives [`VisionError::Degenerate`].
pub fn linear_least_squares(a: &DMatrix<f64>, b: &DVector<f64>) -> Result<DVector<f64>> {
    let (m, n) = a.shape();
    if b.len() != m {
        return Err(VisionError::LengthMismatch {
            first: m,
            second: b.len(),
        });
    }
    if m < n {
        return Err(VisionError::TooFewPoints { needed: n, got: m });
    }
    if a.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(VisionError::InvalidInput(
            "non-finite entry in a least-squares system".into(),
        ));
    }
    let qr = a.clone().qr();
    let r = qr.r();
    let scale = r.diagonal().amax();
    if scale == 0.0 || r.diagonal().iter().any(|d| d.abs() <= 1e-12 * scale) {
        return Err(VisionError::Degenerate(
            "rank-deficient least-squares system".into(),
        ));
    }
    let qtb = qr.q().transpose() * b;
    r.solve_upper_triangular(&qtb)
        .ok_or_else(|| VisionError::Degenerate("rank-deficient least-squares system".into()))
}

/// Solution of min ‖Ax‖ subject to ‖x‖ = 1 with the two smallest singular values of A.
#[derive(Clone, Debug, PartialEq)]
pub struct NullVector {
    /// The unit vector minimizing ‖Ax‖ (the right singular vector of the smallest singular value).
    pub x: DVector<f64>,
    /// Smallest singular value σₙ = ‖Ax‖.
    pub smallest: f64,
    /// Second smallest singular value σₙ₋₁: when it is ≈ σₙ the minimizer is not unique.
    pub second_smallest: f64,
    /// Largest singular value σ₁.
    pub largest: f64,
}

impl NullVector {
    /// True when the minimizer is not unique to relative precision `rel`: σₙ₋₁ ≤ rel·σ₁.
    pub fn is_ambiguous(&self, rel: f64) -> bool {
        self.second_smallest <= rel * self.largest
    }
}

/// min ‖Ax‖ over ‖x‖ = 1 (book §3.4, Theorem 3.2): the last column of V in A = U S Vᵀ.
///
/// A tall A (m > n) is first reduced to its n×n triangular factor R (A = QR has the same right
/// singular vectors), so the SVD costs O(n³) whatever m. A wide A is padded with zero rows.
pub fn min_norm_on_sphere(a: &DMatrix<f64>) -> Result<NullVector> {
    let (m, n) = a.shape();
    if n == 0 {
        return Err(VisionError::InvalidInput("empty system".into()));
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(VisionError::InvalidInput(
            "non-finite entry in a homogeneous system".into(),
        ));
    }
    let square = if m > n {
        a.clone().qr().r()
    } else {
        let mut s = DMatrix::zeros(n, n);
        s.view_mut((0, 0), (m, n)).copy_from(a);
        s
    };
    let svd = square.svd(false, true);
    let vt = svd
        .v_t
        .ok_or_else(|| VisionError::Degenerate("SVD did not converge".into()))?;
    let sv = &svd.singular_values;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| sv[i].total_cmp(&sv[j]));
    let i0 = order[0];
    let x = vt.row(i0).transpose().normalize();
    Ok(NullVector {
        x,
        smallest: sv[i0],
        second_smallest: if n > 1 { sv[order[1]] } else { sv[i0] },
        largest: sv[order[n - 1]],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_line_fit() {
        // y = 2x + 1 sampled exactly.
        let xs = [0.0, 1.0, 2.0, 3.0, 4.0];
        let a = DMatrix::from_fn(5, 2, |i, j| if j == 0 { xs[i] } else { 1.0 });
        let b = DVector::from_iterator(5, xs.iter().map(|x| 2.0 * x + 1.0));
        let x = linear_least_squares(&a, &b).unwrap();
        assert!((x[0] - 2.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12);
        let rank1 = DMatrix::from_fn(5, 2, |i, _| xs[i]);
        assert!(matches!(
            linear_least_squares(&rank1, &b),
            Err(VisionError::Degenerate(_))
        ));
    }

    #[test]
    fn null_vector_of_tall_and_wide_systems() {
        let truth = DVector::from_vec(vec![1.0, -2.0, 0.5, 3.0]).normalize();
        // Rows orthogonal to truth.
        let mut rows = Vec::new();
        for k in 0..7 {
            let r = DVector::from_fn(4, |i, _| (((i + 1) * (k + 2) * (i + k + 3)) as f64).sin());
            let r = &r - &truth * truth.dot(&r);
            rows.push(r.transpose());
        }
        let tall = DMatrix::from_rows(&rows);
        let nv = min_norm_on_sphere(&tall).unwrap();
        assert!(nv.x.dot(&truth).abs() > 1.0 - 1e-12);
        assert!(nv.smallest < 1e-12 && !nv.is_ambiguous(1e-8));
        let wide = DMatrix::from_rows(&rows[..3]);
        let nv = min_norm_on_sphere(&wide).unwrap();
        assert!(nv.x.dot(&truth).abs() > 1.0 - 1e-12);
        let two = DMatrix::from_rows(&rows[..2]);
        assert!(min_norm_on_sphere(&two).unwrap().is_ambiguous(1e-8));
    }
}
