//! Axis–angle parameterization of rotations (book §4.5.2).
//!
//! A rotation of θ radians about the unit axis ω is stored as the 3-vector θω. The conversions
//! below are stable at small angles (Taylor expansions) and near π (the axis is read from the
//! symmetric part of R instead of its antisymmetric part).

use nalgebra::{Matrix3, Vector3};

/// Skew-symmetric matrix `[v]×` such that `[v]× w = v × w`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Rotation matrix of the axis–angle vector `w = θω` (Rodrigues' formula, book §4.5.2).
pub fn axis_angle_to_r(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = w.norm_squared();
    let theta = theta2.sqrt();
    // a = sin θ / θ, b = (1 - cos θ) / θ²
    let (a, b) = if theta < 1e-4 {
        (1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0)
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / theta2)
    };
    let k = skew(w);
    Matrix3::identity() + k * a + k * k * b
}

/// Axis–angle vector `θω`, θ ∈ [0, π], of a rotation matrix (book §4.5.2, eqs. 4.21–4.22).
///
/// `r` should be a rotation; it is not re-orthogonalized.
pub fn r_to_axis_angle(r: &Matrix3<f64>) -> Vector3<f64> {
    let tau = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    let cos = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let sin = 0.5 * tau.norm();
    let theta = sin.atan2(cos);
    if theta < 1e-4 {
        // θ/sin θ ≈ 1 + θ²/6
        return tau * 0.5 * (1.0 + theta * theta / 6.0);
    }
    if cos > -0.9 {
        return tau * (0.5 * theta / sin);
    }
    // Near π: (R + Rᵀ)/2 − cos θ I = (1 − cos θ) ω ωᵀ; take its largest column.
    let s = (r + r.transpose()) * 0.5 - Matrix3::identity() * cos;
    let mut best = 0;
    for i in 1..3 {
        if s[(i, i)] > s[(best, best)] {
            best = i;
        }
    }
    let mut axis = s.column(best).into_owned();
    let n = axis.norm();
    if n == 0.0 {
        return Vector3::zeros();
    }
    axis /= n;
    if axis.dot(&tau) < 0.0 {
        axis = -axis;
    }
    axis * theta
}

/// Right Jacobian of SO(3): `R(w + δ) ≈ R(w) exp([J_r(w) δ]×)`. It gives the analytic
/// derivative `∂(R(w) X)/∂w = −R(w) [X]× J_r(w)` used by the Levenberg–Marquardt models.
pub fn right_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = w.norm_squared();
    let theta = theta2.sqrt();
    let k = skew(w);
    let (a, b) = if theta < 1e-4 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        (
            (1.0 - theta.cos()) / theta2,
            (theta - theta.sin()) / (theta2 * theta),
        )
    };
    Matrix3::identity() - k * a + k * k * b
}

/// Angle in radians of the rotation `a bᵀ` (the geodesic distance between two rotations).
pub fn rotation_angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    r_to_axis_angle(&(a * b.transpose())).norm()
}

/// The rotation nearest to `m` in the Frobenius norm (SVD projection onto SO(3)).
pub fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Matrix3::identity(),
    };
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    u * d * vt
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn check_round_trip(w: Vector3<f64>) {
        let r = axis_angle_to_r(&w);
        assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-12);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        let w2 = r_to_axis_angle(&r);
        let r2 = axis_angle_to_r(&w2);
        assert!((r - r2).norm() < 1e-12, "w={w:?} w2={w2:?}");
        // Compare with nalgebra's implementation.
        let rn = nalgebra::Rotation3::from_scaled_axis(w);
        assert!((rn.matrix() - r).norm() < 1e-12);
    }

    #[test]
    fn round_trips_small_generic_and_near_pi() {
        let axis = Vector3::new(0.3, -0.5, 0.81).normalize();
        for theta in [
            0.0,
            1e-12,
            1e-8,
            1e-5,
            1e-3,
            0.1,
            1.0,
            2.0,
            3.0,
            PI - 1e-3,
            PI - 1e-7,
            PI,
        ] {
            check_round_trip(axis * theta);
        }
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            check_round_trip(axis * PI);
            check_round_trip(axis * (PI - 1e-9));
        }
    }

    #[test]
    fn recovers_axis_angle_exactly() {
        let axis = Vector3::new(-0.2, 0.9, 0.1).normalize();
        for theta in [1e-9, 1e-3, 1.3, PI - 1e-6] {
            let w = axis * theta;
            let w2 = r_to_axis_angle(&axis_angle_to_r(&w));
            assert!(
                (w - w2).norm() < 1e-9 * (1.0 + theta) + 1e-15,
                "{theta}: {w2:?}"
            );
        }
    }

    #[test]
    fn right_jacobian_matches_numeric_derivative() {
        let w = Vector3::new(0.4, -1.1, 0.7);
        let x = Vector3::new(1.0, 2.0, -0.5);
        let analytic = -axis_angle_to_r(&w) * skew(&x) * right_jacobian(&w);
        let h = 1e-6;
        for i in 0..3 {
            let mut wp = w;
            wp[i] += h;
            let mut wm = w;
            wm[i] -= h;
            let d = (axis_angle_to_r(&wp) * x - axis_angle_to_r(&wm) * x) / (2.0 * h);
            assert!((d - analytic.column(i)).norm() < 1e-8);
        }
    }
}
