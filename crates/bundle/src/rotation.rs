//! Axis–angle (Rodrigues) rotations and their analytic Jacobians.
//!
//! The bundle adjuster parameterises every camera rotation by the axis–angle vector ω (rotation by
//! angle ‖ω‖ about the axis ω/‖ω‖), as the book does in section 4.5.2 ("Parameterization of
//! Rotations") and as the BAL files and Ceres' `AngleAxisRotatePoint` do. This file is kept inside
//! `bundle/` on purpose so the bundle adjuster is self-contained.
//!
//! The Jacobian of `R(ω)·X` with respect to ω is `−[R(ω)X]ₓ · J_l(ω)`, where `J_l` is the left
//! Jacobian of SO(3) (Barfoot, "State Estimation for Robotics", eq. 7.86; Gallego & Yezzi, "A
//! compact formula for the derivative of a 3-D rotation in exponential coordinates", 2015).

use nalgebra::{Matrix3, Vector3};

/// Below this angle (radians) the series expansions are used instead of the closed forms.
const SMALL_ANGLE: f64 = 1e-8;

/// The skew-symmetric ("cross-product") matrix `[v]ₓ` such that `[v]ₓ w = v × w`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Rotation matrix of the axis–angle vector ω (Rodrigues' formula, book section 4.5.2).
pub fn angle_axis_to_matrix(omega: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = omega.norm_squared();
    let k = skew(omega);
    if theta2 < SMALL_ANGLE * SMALL_ANGLE {
        return Matrix3::identity() + k;
    }
    let theta = theta2.sqrt();
    let a = theta.sin() / theta;
    let b = (1.0 - theta.cos()) / theta2;
    Matrix3::identity() + k * a + k * k * b
}

/// Axis–angle vector of a rotation matrix (the inverse of [`angle_axis_to_matrix`]), robust near
/// 0 and π (book section 4.5.2; the near-π branch follows Ceres' `RotationMatrixToAngleAxis`).
pub fn matrix_to_angle_axis(r: &Matrix3<f64>) -> Vector3<f64> {
    let rot = nalgebra::Rotation3::from_matrix(r);
    rot.scaled_axis()
}

/// `(R(ω), J_l(ω))`: the rotation and the left Jacobian of SO(3), so that
/// `∂(R(ω)X)/∂ω = −[R(ω)X]ₓ · J_l(ω)` for any X (computed once per camera, used per observation).
pub fn rotation_and_left_jacobian(omega: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let theta2 = omega.norm_squared();
    let k = skew(omega);
    if theta2 < SMALL_ANGLE * SMALL_ANGLE {
        return (Matrix3::identity() + k, Matrix3::identity() + k * 0.5);
    }
    let theta = theta2.sqrt();
    let (s, c) = theta.sin_cos();
    let k2 = k * k;
    let r = Matrix3::identity() + k * (s / theta) + k2 * ((1.0 - c) / theta2);
    let jl = Matrix3::identity() + k * ((1.0 - c) / theta2) + k2 * ((theta - s) / (theta2 * theta));
    (r, jl)
}

/// `R(ω)·X` with Jacobians: returns `(R X, ∂(R X)/∂ω, R)`; `∂(R X)/∂X = R`.
pub fn rotate_with_jacobian(
    omega: &Vector3<f64>,
    x: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let (r, jl) = rotation_and_left_jacobian(omega);
    let rx = r * x;
    (rx, -skew(&rx) * jl, r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_orthogonality() {
        for w in [
            Vector3::new(0.1, -0.2, 0.3),
            Vector3::new(3.0, 0.1, -0.05),
            Vector3::new(1e-10, 0.0, 0.0),
        ] {
            let r = angle_axis_to_matrix(&w);
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
            assert!((matrix_to_angle_axis(&r) - w).norm() < 1e-9);
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let x = Vector3::new(0.3, -1.2, 2.0);
        for w in [
            Vector3::new(0.1, -0.2, 0.3),
            Vector3::new(2.5, 1.0, -0.5),
            Vector3::zeros(),
        ] {
            let (_, j, _) = rotate_with_jacobian(&w, &x);
            for k in 0..3 {
                let h = 1e-6;
                let mut wp = w;
                wp[k] += h;
                let mut wm = w;
                wm[k] -= h;
                let fd =
                    (angle_axis_to_matrix(&wp) * x - angle_axis_to_matrix(&wm) * x) / (2.0 * h);
                assert!(
                    (fd - j.column(k)).norm() < 1e-7,
                    "k={k} fd={fd} j={}",
                    j.column(k)
                );
            }
        }
    }
}
