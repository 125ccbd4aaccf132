//! The reprojection residual and its analytic Jacobians (Triggs et al. 2000, section 2;
//! Hartley & Zisserman 6.1 for the pinhole, Agarwal et al. 2010 / Snavely's Bundler for BAL).
//!
//! For an observation of point X in a camera (ω, t) with intrinsics k the residual is
//! `project(k, ω, t, X) − observed` (2 values); its Jacobian has [`CAMERA_COLUMNS`] camera
//! columns `[ω (3), t (3), k (up to 7)]` and 3 point columns.

use nalgebra::{Matrix2x3, Matrix3, SMatrix, Vector2, Vector3};

use super::camera_model::{CameraModel, Intrinsics, INTRINSICS};
use super::rotation::{angle_axis_to_matrix, rotation_and_left_jacobian, skew};

/// Local camera columns of an observation's Jacobian: ω, t and the intrinsics block's.
pub const CAMERA_COLUMNS: usize = 6 + INTRINSICS;

/// 2×13 Jacobian with respect to `[ω, t, intrinsics]` (columns past a model's parameters are
/// zero).
pub type CameraJacobian = SMatrix<f64, 2, CAMERA_COLUMNS>;

/// 2×7 Jacobian with respect to an intrinsics block's parameters.
type IntrinsicsJacobian = SMatrix<f64, 2, INTRINSICS>;

/// Predicted pixel of X (see [`CameraModel`] for each model's formula).
pub fn project(
    k: &Intrinsics,
    omega: &Vector3<f64>,
    t: &Vector3<f64>,
    x: &Vector3<f64>,
) -> Vector2<f64> {
    project_rt(k, &angle_axis_to_matrix(omega), t, x)
}

/// Predicted pixel of X with the rotation matrix already computed.
pub fn project_rt(
    k: &Intrinsics,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    x: &Vector3<f64>,
) -> Vector2<f64> {
    project_camera_frame(k, &(r * x + t))
}

fn project_camera_frame(k: &Intrinsics, p: &Vector3<f64>) -> Vector2<f64> {
    match k.model {
        CameraModel::Pinhole { aspect, skew } => {
            let [f, cx, cy, ..] = k.params;
            let (xn, yn) = (p.x / p.z, p.y / p.z);
            Vector2::new(f * xn + skew * yn + cx, aspect * f * yn + cy)
        }
        CameraModel::Bal => {
            let [f, k1, k2, ..] = k.params;
            let (px, py) = (-p.x / p.z, -p.y / p.z);
            let r2 = px * px + py * py;
            let d = 1.0 + r2 * (k1 + k2 * r2);
            Vector2::new(f * d * px, f * d * py)
        }
        CameraModel::Radial { .. } => radial(k, p).0,
    }
}

/// The [`CameraModel::Radial`] projection of a camera-frame point P with
/// `(pixel, ∂pixel/∂P, ∂pixel/∂[f, k1, k2, p1, p2, cx, cy])`. Brown–Conrady in closed form; the
/// division model (whose p1, p2 are zero and held) through [`vfxgraph_lens::Distortion`]'s Newton
/// inverse and implicit-function Jacobians (a point where it does not converge projects to NaN,
/// which the solver's step rejects).
fn radial(k: &Intrinsics, p: &Vector3<f64>) -> (Vector2<f64>, Matrix2x3<f64>, IntrinsicsJacobian) {
    let CameraModel::Radial { aspect, skew, lens } = k.model else {
        unreachable!("radial() is called on Radial blocks only")
    };
    let [f, k1, k2, p1, p2, cx, cy] = k.params;
    let iz = 1.0 / p.z;
    let (x, y) = (p.x * iz, p.y * iz);
    let dn = Matrix2x3::new(iz, 0.0, -x * iz, 0.0, iz, -y * iz);
    // q = d(x, y), ∂q/∂(x, y) and ∂q/∂(k1, k2, p1, p2).
    let (q, jq, jk) = match lens {
        vfxgraph_lens::Distortion::Division { .. } => {
            let d = vfxgraph_lens::Distortion::Division { k1, k2 };
            match (
                d.distort([x, y]),
                d.jacobian_point([x, y]),
                d.jacobian_params([x, y]),
            ) {
                (Ok(q), Ok(jq), Ok(jk)) => (
                    q,
                    jq,
                    nalgebra::Matrix2x4::new(
                        jk[(0, 0)],
                        jk[(0, 1)],
                        0.0,
                        0.0,
                        jk[(1, 0)],
                        jk[(1, 1)],
                        0.0,
                        0.0,
                    ),
                ),
                _ => {
                    let nan = Vector2::new(f64::NAN, f64::NAN);
                    return (nan, Matrix2x3::zeros(), IntrinsicsJacobian::zeros());
                }
            }
        }
        _ => {
            let k3 = match lens {
                vfxgraph_lens::Distortion::BrownConrady { k3, .. } => k3,
                _ => 0.0,
            };
            let r2 = x * x + y * y;
            let rho = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let drho = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2); // ∂ρ/∂r²
            let q = [
                rho * x + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                rho * y + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
            ];
            let jq = nalgebra::Matrix2::new(
                rho + 2.0 * drho * x * x + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * drho * x * y + 2.0 * p1 * x + 2.0 * p2 * y,
                2.0 * drho * x * y + 2.0 * p1 * x + 2.0 * p2 * y,
                rho + 2.0 * drho * y * y + 6.0 * p1 * y + 2.0 * p2 * x,
            );
            let jk = nalgebra::Matrix2x4::new(
                r2 * x,
                r2 * r2 * x,
                2.0 * x * y,
                r2 + 2.0 * x * x,
                r2 * y,
                r2 * r2 * y,
                r2 + 2.0 * y * y,
                2.0 * x * y,
            );
            (q, jq, jk)
        }
    };
    let a = nalgebra::Matrix2::new(f, skew, 0.0, aspect * f);
    let pred = Vector2::new(f * q[0] + skew * q[1] + cx, aspect * f * q[1] + cy);
    let ak = a * jk;
    let mut dk = IntrinsicsJacobian::zeros();
    dk[(0, 0)] = q[0];
    dk[(1, 0)] = aspect * q[1];
    dk.fixed_view_mut::<2, 4>(0, 1).copy_from(&ak);
    dk[(0, 5)] = 1.0;
    dk[(1, 6)] = 1.0;
    (pred, a * jq * dn, dk)
}

/// Predicted pixel with its analytic Jacobians: `(prediction, ∂/∂[ω,t,k], ∂/∂X)`.
pub fn project_with_jacobians(
    k: &Intrinsics,
    omega: &Vector3<f64>,
    t: &Vector3<f64>,
    x: &Vector3<f64>,
) -> (Vector2<f64>, CameraJacobian, Matrix2x3<f64>) {
    let (r, jl) = rotation_and_left_jacobian(omega);
    project_with_jacobians_rj(k, &r, &jl, t, x)
}

/// [`project_with_jacobians`] with `(R, J_l)` of the camera's ω precomputed
/// ([`rotation_and_left_jacobian`]), as the solver does once per camera.
pub fn project_with_jacobians_rj(
    k: &Intrinsics,
    r: &Matrix3<f64>,
    jl: &Matrix3<f64>,
    t: &Vector3<f64>,
    x: &Vector3<f64>,
) -> (Vector2<f64>, CameraJacobian, Matrix2x3<f64>) {
    let rx = r * x;
    let d_rx_d_omega = -skew(&rx) * jl;
    let p = rx + t;
    let iz = 1.0 / p.z;
    let (pred, d_pred_d_p, d_pred_d_k): (Vector2<f64>, Matrix2x3<f64>, IntrinsicsJacobian) =
        match k.model {
            CameraModel::Pinhole { aspect, skew } => {
                let [f, cx, cy, ..] = k.params;
                let (xn, yn) = (p.x * iz, p.y * iz);
                // ∂(xn, yn)/∂P
                let dn = Matrix2x3::new(iz, 0.0, -xn * iz, 0.0, iz, -yn * iz);
                let a = nalgebra::Matrix2::new(f, skew, 0.0, aspect * f);
                let pred = Vector2::new(f * xn + skew * yn + cx, aspect * f * yn + cy);
                let mut dk = IntrinsicsJacobian::zeros();
                dk.fixed_view_mut::<2, 3>(0, 0).copy_from(&Matrix2x3::new(
                    xn,
                    1.0,
                    0.0,
                    aspect * yn,
                    0.0,
                    1.0,
                ));
                (pred, a * dn, dk)
            }
            CameraModel::Bal => {
                let [f, k1, k2, ..] = k.params;
                let (px, py) = (-p.x * iz, -p.y * iz);
                let dp = Matrix2x3::new(-iz, 0.0, -px * iz, 0.0, -iz, -py * iz);
                let r2 = px * px + py * py;
                let d = 1.0 + r2 * (k1 + k2 * r2);
                let dd_dr2 = k1 + 2.0 * k2 * r2;
                // ∂pred/∂p = f (d I + 2 dd/dr2 · p pᵀ)
                let c = 2.0 * f * dd_dr2;
                let a = nalgebra::Matrix2::new(
                    f * d + c * px * px,
                    c * px * py,
                    c * px * py,
                    f * d + c * py * py,
                );
                let pred = Vector2::new(f * d * px, f * d * py);
                let mut dk = IntrinsicsJacobian::zeros();
                dk.fixed_view_mut::<2, 3>(0, 0).copy_from(&Matrix2x3::new(
                    d * px,
                    f * r2 * px,
                    f * r2 * r2 * px,
                    d * py,
                    f * r2 * py,
                    f * r2 * r2 * py,
                ));
                (pred, a * dp, dk)
            }
            CameraModel::Radial { .. } => radial(k, &p),
        };
    let d_omega: Matrix2x3<f64> = d_pred_d_p * d_rx_d_omega;
    let d_x: Matrix2x3<f64> = d_pred_d_p * r;
    let mut jc = CameraJacobian::zeros();
    jc.fixed_view_mut::<2, 3>(0, 0).copy_from(&d_omega);
    jc.fixed_view_mut::<2, 3>(0, 3).copy_from(&d_pred_d_p);
    jc.fixed_view_mut::<2, INTRINSICS>(0, 6)
        .copy_from(&d_pred_d_k);
    (pred, jc, d_x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(k: Intrinsics, omega: Vector3<f64>, t: Vector3<f64>, x: Vector3<f64>) {
        check_tol(k, omega, t, x, 1e-6)
    }

    /// `tol`: relative agreement required (the division model's Newton inverse converges to
    /// 1e-12, which central differences of step 1e-8 amplify to ~1e-5).
    fn check_tol(k: Intrinsics, omega: Vector3<f64>, t: Vector3<f64>, x: Vector3<f64>, tol: f64) {
        let (pred, jc, jx) = project_with_jacobians(&k, &omega, &t, &x);
        assert!((pred - project(&k, &omega, &t, &x)).norm() < 1e-12);
        // Parameters: ω (3), t (3), the block's (INTRINSICS), X (3).
        const N: usize = CAMERA_COLUMNS + 3;
        let f = |v: &[f64; N]| {
            let mut kk = k;
            kk.params.copy_from_slice(&v[6..CAMERA_COLUMNS]);
            project(
                &kk,
                &Vector3::new(v[0], v[1], v[2]),
                &Vector3::new(v[3], v[4], v[5]),
                &Vector3::new(
                    v[CAMERA_COLUMNS],
                    v[CAMERA_COLUMNS + 1],
                    v[CAMERA_COLUMNS + 2],
                ),
            )
        };
        let mut base = [0.0; N];
        base[..3].copy_from_slice(omega.as_slice());
        base[3..6].copy_from_slice(t.as_slice());
        base[6..CAMERA_COLUMNS].copy_from_slice(&k.params);
        base[CAMERA_COLUMNS..].copy_from_slice(x.as_slice());
        for i in 0..N {
            let h = 1e-6 * base[i].abs().max(1e-2);
            let mut vp = base;
            vp[i] += h;
            let mut vm = base;
            vm[i] -= h;
            let fd = (f(&vp) - f(&vm)) / (2.0 * h);
            let an = if i < CAMERA_COLUMNS {
                jc.column(i).into_owned()
            } else {
                jx.column(i - CAMERA_COLUMNS).into_owned()
            };
            let tol = tol * (1.0 + an.norm());
            assert!((fd - an).norm() < tol, "param {i}: fd {fd} analytic {an}");
        }
    }

    #[test]
    fn pinhole_jacobians_match_finite_differences() {
        let k = Intrinsics {
            model: CameraModel::Pinhole {
                aspect: 1.05,
                skew: 0.7,
            },
            params: [800.0, 320.0, 240.0, 0.0, 0.0, 0.0, 0.0],
            fixed: false,
            held: [false; INTRINSICS],
        };
        check(
            k,
            Vector3::new(0.1, -0.3, 0.2),
            Vector3::new(0.2, 0.1, 4.0),
            Vector3::new(0.5, -0.4, 1.0),
        );
        check(
            k,
            Vector3::zeros(),
            Vector3::new(0.0, 0.0, 3.0),
            Vector3::new(-0.5, 0.4, 2.0),
        );
    }

    #[test]
    fn radial_jacobians_match_finite_differences() {
        use vfxgraph_lens::Distortion;
        for lens in [
            Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.01,
                p1: 0.0008,
                p2: -0.0005,
            },
            Distortion::Division { k1: -0.1, k2: 0.01 },
        ] {
            let tol = if matches!(lens, Distortion::Division { .. }) {
                1e-4
            } else {
                1e-6
            };
            let mut k = Intrinsics::radial(920.0, 479.5, 269.5, lens);
            if let CameraModel::Radial { aspect, skew, .. } = &mut k.model {
                *aspect = 1.02;
                *skew = 0.3;
            }
            check_tol(
                k,
                Vector3::new(0.1, -0.3, 0.2),
                Vector3::new(0.2, 0.1, 4.0),
                Vector3::new(0.9, -0.6, 1.0),
                tol,
            );
            check_tol(
                k,
                Vector3::zeros(),
                Vector3::new(0.0, 0.0, 3.0),
                Vector3::new(-0.5, 0.4, 2.0),
                tol,
            );
        }
    }

    #[test]
    fn radial_projection_is_the_lens_of_the_camera_model() {
        // The bundle block and the camera type project through the same lens.
        let lens = vfxgraph_lens::Distortion::BrownConrady {
            k1: -0.16,
            k2: 0.045,
            k3: 0.0,
            p1: 0.0008,
            p2: -0.0005,
        };
        let k = Intrinsics::radial(920.0, 479.5, 269.5, lens);
        let cam = vfxgraph_geometry::camera::Intrinsics::new(920.0, 920.0, 479.5, 269.5)
            .with_distortion(lens);
        let x = Vector3::new(0.7, -0.45, 1.3);
        let a = project(&k, &Vector3::zeros(), &Vector3::zeros(), &x);
        let b = cam.project_camera_point(&x).unwrap();
        assert!(
            (a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9,
            "{a} vs {b}"
        );
    }

    #[test]
    fn bal_jacobians_match_finite_differences() {
        let k = Intrinsics::bal(500.0, -0.1, 0.02, false);
        check(
            k,
            Vector3::new(0.1, -0.3, 0.2),
            Vector3::new(0.2, 0.1, -4.0),
            Vector3::new(0.5, -0.4, 1.0),
        );
        check(
            k,
            Vector3::new(2.0, 1.0, -0.5),
            Vector3::new(-1.0, 0.3, -6.0),
            Vector3::new(0.2, 0.1, 0.3),
        );
    }
}
