//! The motions a plane-induced homography allows: H = R + t nᵀ/d between calibrated views
//! decomposed by its singular values, after Faugeras & Lustman, "Motion and structure from
//! motion in a piecewise planar environment" (IJPRAI 1988); see also Malis & Vargas, "Deeper
//! understanding of the homography decomposition for vision-based control" (INRIA RR-6303, 2007).
//!
//! A floor or a wall seen from two frames is explained by a homography, where the fundamental
//! matrix of §5.7 is not determined; with K known the homography still gives the motion: four
//! decompositions, two of which put the plane in front of both cameras. [`planar_poses`] returns
//! those (the caller tells them apart with a third view or the scene's points).

use nalgebra::{Matrix3, Vector3};

/// One decomposition of a calibrated homography: x_b ~ (R + t nᵀ) x_a for points X of the plane
/// nᵀX = d in camera a's frame (so t is the translation over the plane's distance).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarMotion {
    /// Rotation from camera a to camera b.
    pub r: Matrix3<f64>,
    /// Translation over the plane's distance from camera a.
    pub t: Vector3<f64>,
    /// The plane's unit normal in camera a's frame (nᵀX = d > 0 for the plane's points: the
    /// decomposition whose points are in front has nᵀx > 0 for their rays x).
    pub n: Vector3<f64>,
}

/// Every decomposition (four, or one for a pure rotation with t = 0) of the calibrated
/// homography `h` (K_b⁻¹ H K_a, any scale and sign). Empty when `h` is singular or not finite.
pub fn decompose_homography(h: &Matrix3<f64>) -> Vec<PlanarMotion> {
    if !h.iter().all(|v| v.is_finite()) {
        return Vec::new();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Vec::new();
    };
    // Singular values in decreasing order, with U and V's columns permuted alike.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let d = order.map(|i| svd.singular_values[i]);
    if !(d[2] > 1e-12 * d[0]) {
        return Vec::new();
    }
    let u = Matrix3::from_columns(&order.map(|i| u.column(i).into_owned()));
    let v = Matrix3::from_columns(&order.map(|i| vt.row(i).transpose()));
    let (d1, d2, d3) = (d[0] / d[1], 1.0, d[2] / d[1]);
    let s = u.determinant() * v.determinant();
    if d1 - d3 < 1e-9 {
        // Pure rotation: H/σ₂ is the rotation itself (up to sign).
        let r = u * v.transpose() * s;
        return vec![PlanarMotion {
            r,
            t: Vector3::zeros(),
            n: Vector3::z(),
        }];
    }
    let den = d1 * d1 - d3 * d3;
    let x1 = ((d1 * d1 - d2 * d2) / den).max(0.0).sqrt();
    let x3 = ((d2 * d2 - d3 * d3) / den).max(0.0).sqrt();
    let sin_mag = ((d1 * d1 - d2 * d2) * (d2 * d2 - d3 * d3)).max(0.0).sqrt() / ((d1 + d3) * d2);
    let cos = (d2 * d2 + d1 * d3) / ((d1 + d3) * d2);
    let mut out = Vec::with_capacity(4);
    for (e1, e3) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let sin = e1 * e3 * sin_mag;
        let rp = Matrix3::new(cos, 0.0, -sin, 0.0, 1.0, 0.0, sin, 0.0, cos);
        let tp = Vector3::new(e1 * x1, 0.0, -e3 * x3) * (d1 - d3);
        let np = Vector3::new(e1 * x1, 0.0, e3 * x3);
        // H/σ₂ = d′R′ + t′n′ᵀ in the SVD's frames, with d = s·d′ (here d′ = 1).
        let r = u * rp * v.transpose() * s;
        // H/σ₂ = s·(R + s·t nᵀ): the motion over the plane's distance.
        let t = u * tp * s;
        let n = (v * np).normalize();
        out.push(PlanarMotion { r, t, n });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::{axis_angle_to_r, rotation_angle_between};
    use crate::synthetic::gaussian;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    #[test]
    fn recovers_the_motion_among_its_decompositions() {
        let mut rng = Pcg64::seed_from_u64(3);
        for _ in 0..200 {
            let r = axis_angle_to_r(
                &Vector3::new(gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng))
                    .scale(0.3),
            );
            let t = Vector3::new(gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng));
            let n =
                Vector3::new(gaussian(&mut rng) * 0.5, gaussian(&mut rng) * 0.5, 1.0).normalize();
            let dist = 3.0 + gaussian(&mut rng).abs();
            let h = (r + t * n.transpose() / dist) * (-1.7);
            let all = decompose_homography(&h);
            assert_eq!(all.len(), 4);
            let best = all
                .iter()
                .map(|m| {
                    rotation_angle_between(&m.r, &r) + (m.t - t / dist).norm() + (m.n - n).norm()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(best < 1e-8, "{best}");
            // Every decomposition explains the homography and is a proper rotation.
            let hn = r + t * n.transpose() / dist;
            for m in &all {
                assert!((m.r.determinant() - 1.0).abs() < 1e-9);
                let hm = m.r + m.t * m.n.transpose();
                let scale = hn.norm() / hm.norm();
                let err = (hm * scale - hn).norm().min((hm * scale + hn).norm());
                assert!(err < 1e-8 * hn.norm(), "{err}");
            }
        }
    }

    #[test]
    fn a_pure_rotation_has_no_translation() {
        let r = axis_angle_to_r(&Vector3::new(0.1, -0.2, 0.05));
        let all = decompose_homography(&(r * 2.0));
        assert_eq!(all.len(), 1);
        assert!(rotation_angle_between(&all[0].r, &r) < 1e-9);
        assert_eq!(all[0].t, Vector3::zeros());
    }

    #[test]
    fn singular_and_nan_give_nothing() {
        assert!(decompose_homography(&Matrix3::zeros()).is_empty());
        assert!(decompose_homography(&Matrix3::from_element(f64::NAN)).is_empty());
    }
}
