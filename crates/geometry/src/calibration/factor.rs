//! Isolation of the camera parameters: factoring P = λK[R|t] (book §4.3, `calib_camfactor`),
//! with the sign correction that makes f1, f2 > 0 for pixels with the origin at the top left.

use nalgebra::{Matrix3x4, Vector3};

use crate::camera::{Camera, Intrinsics};
use crate::error::{Result, VisionError};

/// Factor a 3×4 camera matrix into K[R|t] (book §4.3): λ = ‖a₃‖, R₃ = a₃/λ, v0 = a₂'·R₃,
/// u0 = a₁'·R₃, f2 = ‖a₂' − v0R₃‖, R₂ = (a₂' − v0R₃)/f2, R₁ = R₂ × R₃, s = a₁'·R₂, f1 = a₁'·R₁,
/// then t; if f1 < 0 the sign of λ was wrong and (f1, R₂, R₃, t₂, t₃) change sign.
///
/// The result satisfies det R = +1, f1 > 0, f2 > 0 and K[R|t] = P/λ.
pub fn factor_camera(p: &Matrix3x4<f64>) -> Result<Camera> {
    if p.iter().any(|v| !v.is_finite()) {
        return Err(VisionError::InvalidInput("P has a non-finite entry".into()));
    }
    let a3: Vector3<f64> = p.fixed_view::<1, 3>(2, 0).transpose();
    let lambda = a3.norm();
    if lambda <= 1e-300 || lambda <= 1e-14 * p.norm() {
        return Err(VisionError::Degenerate(
            "P has a zero third row: camera at infinity".into(),
        ));
    }
    let pt = p / lambda;
    let a1: Vector3<f64> = pt.fixed_view::<1, 3>(0, 0).transpose();
    let a2: Vector3<f64> = pt.fixed_view::<1, 3>(1, 0).transpose();
    let mut r3 = a3 / lambda;
    let v0 = a2.dot(&r3);
    let u0 = a1.dot(&r3);
    let aux = a2 - r3 * v0;
    let f2 = aux.norm();
    if f2 <= 1e-14 * a2.norm().max(1.0) {
        return Err(VisionError::Degenerate(
            "P is rank deficient (f2 = 0)".into(),
        ));
    }
    let mut r2 = aux / f2;
    let s = a1.dot(&r2);
    let r1 = r2.cross(&r3);
    let mut f1 = a1.dot(&r1);
    if f1.abs() <= 1e-14 * a1.norm().max(1.0) {
        return Err(VisionError::Degenerate(
            "P is rank deficient (f1 = 0)".into(),
        ));
    }
    let mut t3 = pt[(2, 3)];
    let mut t2 = (pt[(1, 3)] - v0 * t3) / f2;
    let t1 = (pt[(0, 3)] - u0 * t3 - s * t2) / f1;
    if f1 < 0.0 {
        t2 = -t2;
        t3 = -t3;
        f1 = -f1;
        r3 = -r3;
        r2 = -r2;
    }
    let r = nalgebra::Matrix3::from_rows(&[r1.transpose(), r2.transpose(), r3.transpose()]);
    let k = Intrinsics {
        f1,
        f2,
        s,
        u0,
        v0,
        width: None,
        height: None,
        distortion: crate::lens::Distortion::None,
    };
    Ok(Camera::new(k, r, Vector3::new(t1, t2, t3)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::synthetic::random_camera;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    #[test]
    fn factor_recovers_k_r_t_for_either_sign_of_lambda() {
        let mut rng = Pcg64::seed_from_u64(11);
        for _ in 0..20 {
            let mut cam = random_camera(&mut rng);
            cam.intrinsics.s = 2.5;
            let p = cam.p_matrix();
            for lambda in [3.7, -0.02] {
                let f = factor_camera(&(p * lambda)).unwrap();
                assert!((f.intrinsics.k() - cam.intrinsics.k()).norm() < 1e-8 * 1000.0);
                assert!((f.pose.r - cam.pose.r).norm() < 1e-10);
                assert!((f.pose.t - cam.pose.t).norm() < 1e-9);
                assert!((f.pose.r.determinant() - 1.0).abs() < 1e-12);
            }
        }
        assert!(factor_camera(&Matrix3x4::zeros()).is_err());
    }
}
