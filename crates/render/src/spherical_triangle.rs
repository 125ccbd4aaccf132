//! Sampling a triangle by the solid angle it subtends (book §9.11 samples lights by area; this
//! is the "by solid angle where cheap" variant): J. Arvo, *Stratified Sampling of Spherical
//! Triangles*, SIGGRAPH 1995, in the form of pbrt-v4 `SampleSphericalTriangle` (§6.5.4).
//! Directions are uniform over the spherical triangle, so the pdf is 1/Ω (solid angle): the
//! 1/r² and cos θ_light factors of area sampling are absorbed exactly.

use std::f64::consts::PI;

use crate::math::Vec3;

/// Solid angle subtended at `p` by the triangle (a, b, c) (Van Oosterom & Strackee 1983):
/// Ω = 2 atan2(|â·(b̂×ĉ)|, 1 + â·b̂ + b̂·ĉ + ĉ·â).
pub fn solid_angle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f64 {
    let (a, b, c) = (
        (a - p).normalized(),
        (b - p).normalized(),
        (c - p).normalized(),
    );
    let num = a.dot(b.cross(c)).abs();
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    let o = 2.0 * num.atan2(den);
    if o.is_finite() {
        o
    } else {
        0.0
    }
}

fn gram_schmidt(v: Vec3, w: Vec3) -> Vec3 {
    v - w * v.dot(w)
}

fn angle_between(v1: Vec3, v2: Vec3) -> f64 {
    // Numerically robust for nearly (anti)parallel vectors.
    if v1.dot(v2) < 0.0 {
        PI - 2.0 * ((v1 + v2).length() / 2.0).min(1.0).asin()
    } else {
        2.0 * ((v2 - v1).length() / 2.0).min(1.0).asin()
    }
}

/// A direction from `p` uniform over the spherical triangle (a, b, c), with its pdf 1/Ω in
/// solid angle; `None` when the triangle is degenerate as seen from `p` (Ω ≈ 0 or `p` in its
/// plane).
pub fn sample(p: Vec3, tri: [Vec3; 3], u: [f64; 2]) -> Option<(Vec3, f64)> {
    let a = (tri[0] - p).normalized();
    let b = (tri[1] - p).normalized();
    let c = (tri[2] - p).normalized();
    let (nab, nbc, nca) = (a.cross(b), b.cross(c), c.cross(a));
    let (lab, lbc, lca) = (nab.length(), nbc.length(), nca.length());
    if !(lab > 0.0 && lbc > 0.0 && lca > 0.0) {
        return None;
    }
    let (nab, nbc, nca) = (nab / lab, nbc / lbc, nca / lca);
    let alpha = angle_between(nab, -nca);
    let beta = angle_between(nbc, -nab);
    let gamma = angle_between(nca, -nbc);
    // Spherical excess = area; pick the sub-triangle area A' uniformly in [0, A].
    let a_pi = alpha + beta + gamma;
    let area = a_pi - PI;
    if area.is_nan() || area <= 1e-12 || area.is_infinite() {
        return None;
    }
    let ap_pi = PI + u[0] * (a_pi - PI);
    let (sin_alpha, cos_alpha) = alpha.sin_cos();
    let (sin_app, cos_app) = ap_pi.sin_cos();
    let sin_phi = sin_app * cos_alpha - cos_app * sin_alpha;
    let cos_phi = cos_app * cos_alpha + sin_app * sin_alpha;
    let k1 = cos_phi + cos_alpha;
    let k2 = sin_phi - sin_alpha * a.dot(b);
    let den = (k2 * sin_phi + k1 * cos_phi) * sin_alpha;
    let cos_bp = if den != 0.0 {
        ((k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / den).clamp(-1.0, 1.0)
    } else {
        1.0
    };
    let sin_bp = (1.0 - cos_bp * cos_bp).max(0.0).sqrt();
    let ca = gram_schmidt(c, a);
    let lca = ca.length();
    if lca == 0.0 {
        return None;
    }
    let cp = a * cos_bp + ca * (sin_bp / lca);
    // Then the point along the arc from b to c'.
    let cos_theta = 1.0 - u[1] * (1.0 - cp.dot(b));
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let cb = gram_schmidt(cp, b);
    let lcb = cb.length();
    let w = if lcb > 0.0 {
        b * cos_theta + cb * (sin_theta / lcb)
    } else {
        b
    };
    let w = w.normalized();
    if !w.is_finite() {
        return None;
    }
    Some((w, 1.0 / area))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::Ray;
    use crate::shape::Triangle;
    use rand_core::SeedableRng;

    fn u2(rng: &mut rand_pcg::Pcg32) -> [f64; 2] {
        use rand_core::RngCore;
        let f = |x: u32| x as f64 / 4_294_967_296.0;
        [f(rng.next_u32()), f(rng.next_u32())]
    }

    /// Triangles seen from the origin: small and far, large and near, nearly grazing.
    fn cases() -> Vec<[Vec3; 3]> {
        vec![
            [
                Vec3::new(-1.0, -1.0, 2.0),
                Vec3::new(1.5, -0.5, 2.2),
                Vec3::new(0.0, 1.0, 1.8),
            ],
            [
                Vec3::new(-3.0, -3.0, 0.3),
                Vec3::new(3.0, -2.0, 0.4),
                Vec3::new(0.0, 4.0, 0.2),
            ],
            [
                Vec3::new(0.1, 0.1, 5.0),
                Vec3::new(0.3, 0.1, 5.0),
                Vec3::new(0.1, 0.25, 5.1),
            ],
        ]
    }

    #[test]
    fn solid_angle_matches_a_closed_form() {
        // One face of a cube seen from its centre: 4π/6; an octant triangle: π/2.
        let o = Vec3::ZERO;
        let face = [
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, -1.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(-1.0, 1.0, 1.0),
        ];
        let s =
            solid_angle(o, face[0], face[1], face[2]) + solid_angle(o, face[0], face[2], face[3]);
        assert!((s - 4.0 * PI / 6.0).abs() < 1e-12, "{s}");
        let oct = solid_angle(
            o,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        );
        assert!((oct - PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn samples_hit_the_triangle_and_the_pdf_is_one_over_the_solid_angle() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(9);
        for t in cases() {
            let tri = Triangle::new(t[0], t[1], t[2]).unwrap();
            let omega = solid_angle(Vec3::ZERO, t[0], t[1], t[2]);
            let mut missed = 0;
            for _ in 0..2000 {
                let (w, pdf) = sample(Vec3::ZERO, t, u2(&mut rng)).unwrap();
                assert!((w.length() - 1.0).abs() < 1e-9);
                assert!((pdf * omega - 1.0).abs() < 1e-6, "{pdf} {omega}");
                // Every sampled direction hits the triangle (rounding at the edges aside).
                if tri
                    .intersect(&Ray::new(Vec3::ZERO, w), f64::INFINITY)
                    .is_none()
                {
                    missed += 1;
                }
            }
            assert!(missed <= 2, "{missed} of 2000 samples miss {t:?}");
        }
    }

    #[test]
    fn samples_are_uniform_in_solid_angle_chi_square() {
        // Split the triangle at its midpoints into 4 sub-triangles; each receives samples in
        // proportion to ITS solid angle (not its area) when sampling is uniform in solid angle.
        let mut rng = rand_pcg::Pcg32::seed_from_u64(4);
        for t in cases() {
            let m = [
                (t[0] + t[1]) * 0.5,
                (t[1] + t[2]) * 0.5,
                (t[2] + t[0]) * 0.5,
            ];
            let subs = [
                [t[0], m[0], m[2]],
                [m[0], t[1], m[1]],
                [m[2], m[1], t[2]],
                [m[0], m[1], m[2]],
            ];
            let total = solid_angle(Vec3::ZERO, t[0], t[1], t[2]);
            let tris: Vec<Triangle> = subs
                .iter()
                .map(|s| Triangle::new(s[0], s[1], s[2]).unwrap())
                .collect();
            let n = 40_000;
            let mut counts = [0usize; 4];
            let mut missed = 0usize;
            for _ in 0..n {
                let (w, _) = sample(Vec3::ZERO, t, u2(&mut rng)).unwrap();
                let ray = Ray::new(Vec3::ZERO, w);
                match tris
                    .iter()
                    .position(|s| s.intersect(&ray, f64::INFINITY).is_some())
                {
                    Some(k) => counts[k] += 1,
                    None => missed += 1,
                }
            }
            assert!(missed < 5, "{missed} samples missed");
            let chi2: f64 = subs
                .iter()
                .zip(counts)
                .map(|(s, c)| {
                    let e = n as f64 * solid_angle(Vec3::ZERO, s[0], s[1], s[2]) / total;
                    (c as f64 - e).powi(2) / e
                })
                .sum();
            assert!(chi2 < 16.3, "chi2 {chi2} (3 dof, p = 0.001) {counts:?}");
        }
    }

    #[test]
    fn pdf_integrates_to_one() {
        // ∫ pdf dω over the sphere = (1/Ω)·Ω: estimated by uniform sphere directions, counting
        // those that hit the triangle.
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        let t = cases()[1];
        let tri = Triangle::new(t[0], t[1], t[2]).unwrap();
        let pdf = 1.0 / solid_angle(Vec3::ZERO, t[0], t[1], t[2]);
        let n = 400_000;
        let mut acc = 0.0;
        for _ in 0..n {
            let (w, p) = crate::sampling::uniform_sphere(u2(&mut rng));
            if tri
                .intersect(&Ray::new(Vec3::ZERO, w), f64::INFINITY)
                .is_some()
            {
                acc += pdf / p;
            }
        }
        let est = acc / n as f64;
        assert!((est - 1.0).abs() < 0.02, "{est}");
    }
}
