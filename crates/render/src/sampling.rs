//! Sampling routines: each returns its sample and states the pdf's measure (pbrt-v4 §A.5;
//! book §9.7–9.9 for Monte Carlo integration and hemisphere sampling).

use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

use crate::math::Vec3;

/// Concentric mapping of the unit square onto the unit disk (Shirley & Chiu 1997), used by
/// [`cosine_hemisphere`]: area-preserving and low-distortion.
#[inline]
pub fn concentric_disk(u: [f64; 2]) -> (f64, f64) {
    let (a, b) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, theta) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, FRAC_PI_2 - FRAC_PI_4 * (a / b))
    };
    (r * theta.cos(), r * theta.sin())
}

/// A cosine-weighted direction on the hemisphere around +z (Malley's method) with its pdf
/// cos θ / π in solid angle: the importance sampling of the Lambertian BRDF (book §9.5.1, §9.9).
#[inline]
pub fn cosine_hemisphere(u: [f64; 2]) -> (Vec3, f64) {
    let (x, y) = concentric_disk(u);
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    (Vec3::new(x, y, z), z * FRAC_1_PI)
}

/// The pdf of [`cosine_hemisphere`] for a local direction (zero below the horizon).
#[inline]
pub fn cosine_hemisphere_pdf(w: Vec3) -> f64 {
    w.z.max(0.0) * FRAC_1_PI
}

/// A uniform direction on the hemisphere around +z with pdf 1/(2π) — the book's sampler (§9.9),
/// kept for tests and comparisons.
#[inline]
pub fn uniform_hemisphere(u: [f64; 2]) -> (Vec3, f64) {
    let z = u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    (Vec3::new(r * phi.cos(), r * phi.sin(), z), 0.5 * FRAC_1_PI)
}

/// A uniform direction on the unit sphere with pdf 1/(4π).
#[inline]
pub fn uniform_sphere(u: [f64; 2]) -> (Vec3, f64) {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    (Vec3::new(r * phi.cos(), r * phi.sin(), z), 0.25 * FRAC_1_PI)
}

/// Uniform barycentrics (b0, b1, b2) on a triangle, pdf 1/area in area measure (book §9.11;
/// the square-root parameterization, pbrt-v4 §6.5.4).
#[inline]
pub fn uniform_triangle(u: [f64; 2]) -> [f64; 3] {
    let su = u[0].sqrt();
    let b0 = 1.0 - su;
    let b1 = u[1] * su;
    [b0, b1, 1.0 - b0 - b1]
}

/// Veach's power heuristic (β = 2) weight of strategy f against g, each with one sample
/// (Veach & Guibas 1995; pbrt-v4 §2.2.3).
#[inline]
pub fn power_heuristic(f_pdf: f64, g_pdf: f64) -> f64 {
    let (f, g) = (f_pdf * f_pdf, g_pdf * g_pdf);
    if f.is_infinite() {
        return 1.0;
    }
    if f + g == 0.0 {
        0.0
    } else {
        f / (f + g)
    }
}

/// A piecewise-constant 1D distribution over `n` items (a discrete CDF), for choosing a light
/// in proportion to its power (pbrt-v4 `PiecewiseConstant1D`, discrete use).
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    cdf: Vec<f64>,
    pmf: Vec<f64>,
}

impl Distribution1D {
    /// From non-negative weights. Returns `None` if there are none or they sum to zero (or are
    /// not finite).
    pub fn new(weights: &[f64]) -> Option<Self> {
        let total: f64 = weights.iter().map(|w| w.max(0.0)).sum();
        if weights.is_empty() || !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let pmf: Vec<f64> = weights.iter().map(|w| w.max(0.0) / total).collect();
        let mut cdf = Vec::with_capacity(pmf.len());
        let mut acc = 0.0;
        for p in &pmf {
            acc += p;
            cdf.push(acc);
        }
        *cdf.last_mut().expect("non-empty") = 1.0;
        Some(Distribution1D { cdf, pmf })
    }
    /// Number of items.
    pub fn len(&self) -> usize {
        self.pmf.len()
    }
    /// True when there are no items.
    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }
    /// Picks an item for `u` in [0, 1): (index, probability).
    #[inline]
    pub fn sample(&self, u: f64) -> (usize, f64) {
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.pmf.len() - 1);
        (i, self.pmf[i])
    }
    /// The probability of item `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f64 {
        self.pmf[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::{RngCore, SeedableRng};

    fn u2(rng: &mut rand_pcg::Pcg32) -> [f64; 2] {
        [unit(rng.next_u64()), unit(rng.next_u64())]
    }
    fn unit(x: u64) -> f64 {
        (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    #[test]
    fn sampled_directions_are_unit_and_pdfs_agree() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(1);
        for _ in 0..1000 {
            let (w, pdf) = cosine_hemisphere(u2(&mut rng));
            assert!((w.length() - 1.0).abs() < 1e-12 && w.z >= 0.0);
            assert!((pdf - cosine_hemisphere_pdf(w)).abs() < 1e-12);
            let (w, _) = uniform_sphere(u2(&mut rng));
            assert!((w.length() - 1.0).abs() < 1e-12);
            let b = uniform_triangle(u2(&mut rng));
            assert!(b.iter().all(|&x| (-1e-15..=1.0).contains(&x)));
        }
    }

    #[test]
    fn triangle_samples_are_uniform() {
        // Split the triangle (0,0),(1,0),(0,1) at x+y = 1/sqrt2... use four congruent
        // sub-triangles by midpoints: each must get 1/4 of the samples.
        let mut rng = rand_pcg::Pcg32::seed_from_u64(2);
        let mut counts = [0usize; 4];
        let n = 40_000;
        for _ in 0..n {
            let b = uniform_triangle(u2(&mut rng));
            let (x, y) = (b[1], b[2]);
            let k = if x > 0.5 {
                0
            } else if y > 0.5 {
                1
            } else if x + y < 0.5 {
                2
            } else {
                3
            };
            counts[k] += 1;
        }
        let chi2: f64 = counts
            .iter()
            .map(|&c| (c as f64 - n as f64 / 4.0).powi(2) / (n as f64 / 4.0))
            .sum();
        assert!(
            chi2 < 16.3,
            "chi2 {chi2} with 3 dof (p = 0.001), {counts:?}"
        );
    }

    #[test]
    fn distribution_picks_in_proportion() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]).unwrap();
        assert_eq!(d.sample(0.0), (0, 0.25));
        assert_eq!(d.sample(0.2499).0, 0);
        assert_eq!(d.sample(0.25).0, 2);
        assert_eq!(d.sample(0.999999).0, 2);
        assert_eq!(d.pmf(1), 0.0);
        assert!(Distribution1D::new(&[0.0, 0.0]).is_none());
        assert!(Distribution1D::new(&[f64::NAN]).is_none());
        assert!(Distribution1D::new(&[]).is_none());
    }

    #[test]
    fn power_heuristic_limits() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-15);
        assert_eq!(power_heuristic(f64::INFINITY, 1.0), 1.0);
    }
}
