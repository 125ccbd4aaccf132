//! The essential matrix and the relative pose (book §5.8): E = K_bᵀ F K_a (eq. 5.4), its four
//! factorizations [R|t] (Theorem 5.3) and the choice of the one that puts the points in front of
//! both cameras (§5.8.1).

use nalgebra::{Matrix3, Point2, Vector3};

use super::triangulation::triangulate_linear;
use crate::camera::{Camera, Intrinsics, Pose};
use crate::error::{check_pairs, Result, VisionError};
use crate::rotation::skew;

/// E = K_bᵀ F K_a (book eq. 5.4, `calib_ematrix_make`).
pub fn essential_from_fundamental(
    f: &Matrix3<f64>,
    ka: &Intrinsics,
    kb: &Intrinsics,
) -> Matrix3<f64> {
    kb.k().transpose() * f * ka.k()
}

/// F = K_b⁻ᵀ \[t\]× R K_a⁻¹ of the cameras K_a[I|0] and K_b[R|t].
pub fn fundamental_from_pose(ka: &Intrinsics, kb: &Intrinsics, pose: &Pose) -> Matrix3<f64> {
    kb.k_inv().transpose() * skew(&pose.t) * pose.r * ka.k_inv()
}

/// The four candidate poses [R|t] of camera B relative to A = [I|0] (book Theorem 5.3 and
/// §5.8.1, `calib_ematrix_get_all_rt`): R ∈ {UWVᵀ, UWᵀVᵀ}, t = ±U(0, 0, 1)ᵀ, ‖t‖ = 1.
pub fn decompose_essential(e: &Matrix3<f64>) -> Result<[Pose; 4]> {
    if e.iter().any(|v| !v.is_finite()) || e.norm() == 0.0 {
        return Err(VisionError::InvalidInput(
            "E must be finite and non-zero".into(),
        ));
    }
    let svd = e.svd(true, true);
    let (mut u, mut vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(VisionError::Degenerate("SVD of E failed".into())),
    };
    // Put the zero singular value last.
    let s = svd.singular_values;
    let (imin, _) = s.argmin();
    if imin != 2 {
        u.swap_columns(imin, 2);
        vt.swap_rows(imin, 2);
    }
    if u.determinant() < 0.0 {
        u = -u;
    }
    if vt.determinant() < 0.0 {
        vt = -vt;
    }
    let w = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let r1 = u * w * vt;
    let r2 = u * w.transpose() * vt;
    let t: Vector3<f64> = u.column(2).into_owned();
    Ok([
        Pose::new(r1, t),
        Pose::new(r1, -t),
        Pose::new(r2, t),
        Pose::new(r2, -t),
    ])
}

/// The candidate pose of camera B that puts the most matches in front of both cameras (book
/// §5.8.1; the book tests one match, this counts all of them). Returns the pose and the
/// per-match cheirality flags.
pub fn choose_pose(
    e: &Matrix3<f64>,
    ka: &Intrinsics,
    kb: &Intrinsics,
    a: &[Point2<f64>],
    b: &[Point2<f64>],
) -> Result<(Pose, Vec<bool>)> {
    check_pairs(a.len(), b.len(), 1)?;
    let cam_a = Camera::new(ka.clone(), Matrix3::identity(), Vector3::zeros());
    let pa = cam_a.p_matrix();
    let mut best: Option<(usize, Pose, Vec<bool>)> = None;
    for pose in decompose_essential(e)? {
        let cam_b = Camera {
            intrinsics: kb.clone(),
            pose: pose.clone(),
        };
        let pb = cam_b.p_matrix();
        let flags: Vec<bool> = a
            .iter()
            .zip(b)
            .map(|(xa, xb)| match triangulate_linear(&pa, &pb, xa, xb) {
                Ok(x) => cam_a.depth(&x) > 0.0 && cam_b.depth(&x) > 0.0,
                Err(_) => false,
            })
            .collect();
        let count = flags.iter().filter(|&&f| f).count();
        if best.as_ref().is_none_or(|(c, _, _)| count > *c) {
            best = Some((count, pose, flags));
        }
    }
    match best {
        Some((c, pose, flags)) if c > 0 => Ok((pose, flags)),
        _ => Err(VisionError::Degenerate(
            "no point lies in front of both cameras".into(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::rotation_angle_between;
    use crate::two_view::tests::two_view_scene;

    #[test]
    fn decomposition_contains_the_truth_and_cheirality_picks_it() {
        let s = two_view_scene(3, 30, 0.0, 0.0);
        let e = essential_from_fundamental(&s.fundamental(), &s.k, &s.k);
        let poses = decompose_essential(&e).unwrap();
        let t_true = s.pose_b.t.normalize();
        assert!(poses
            .iter()
            .any(|p| rotation_angle_between(&p.r, &s.pose_b.r) < 1e-9
                && (p.t - t_true).norm() < 1e-9));
        for p in &poses {
            assert!((p.r.determinant() - 1.0).abs() < 1e-12);
        }
        let (pose, flags) = choose_pose(&e, &s.k, &s.k, &s.a, &s.b).unwrap();
        assert!(rotation_angle_between(&pose.r, &s.pose_b.r) < 1e-9);
        assert!((pose.t - t_true).norm() < 1e-9);
        assert!(flags.iter().all(|&f| f));
    }
}
