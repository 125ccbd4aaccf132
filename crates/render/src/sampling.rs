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

/// A piecewise-constant 1-D distribution with `n` equal pieces (pbrt's `Distribution1D`,
/// *Physically Based Rendering* 3rd ed. §13.6.7; `PiecewiseConstant1D` in pbrt-v4 §A.5.4): the
/// one distribution of the renderer, sampled continuously on `[0, 1)` (the dome's rows and
/// marginal, [`Distribution1D::sample`]) or discretely over its `n` items (a light triangle in
/// proportion to its power, [`Distribution1D::sample_discrete`]).
///
/// The cumulative sum is tabulated and inverted by a search narrowed by a guide table (Chen &
/// Asau's "cutpoint" method: for each of `n` equal slices of `[0, 1]`, the first cdf entry above
/// it), so a sample reads a few neighbouring entries instead of bisecting the whole table — the
/// same inversion, in expected constant time.
///
/// Both uses pick the piece whose cdf interval holds `u` (zero-mass pieces are never picked).
/// A discrete pick's probability is the piece's value over the plain sum of the values
/// (`w / Σw`, exactly what a light's weights give), not `(cdf[i+1] − cdf[i])`, which differs from
/// it in the last bits.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f64>,
    cdf: Vec<f64>,
    /// `guide[k]` = the number of cdf entries ≤ k/n, for k in 0..=n.
    guide: Vec<u32>,
    integral: f64,
    /// `Σ func`, summed in order: the discrete pmf's denominator.
    sum: f64,
}

impl Distribution1D {
    /// From non-negative piece values (NaN, infinities and negatives count as 0). An all-zero
    /// function becomes uniform, so sampling never fails.
    pub fn new(func: &[f64]) -> Distribution1D {
        let n = func.len().max(1);
        let mut f: Vec<f64> = func
            .iter()
            .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
            .collect();
        f.resize(n, 0.0);
        let mut cdf = vec![0.0; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + f[i] / n as f64;
        }
        let mut integral = cdf[n];
        if integral <= 0.0 {
            f.iter_mut().for_each(|v| *v = 1.0);
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n as f64;
            }
            integral = 1.0;
        } else {
            for c in &mut cdf {
                *c /= integral;
            }
        }
        let guide = (0..=n)
            .map(|k| {
                let b = k as f64 / n as f64;
                cdf.partition_point(|&c| c <= b) as u32
            })
            .collect();
        let sum = f.iter().sum();
        Distribution1D {
            func: f,
            cdf,
            guide,
            integral,
            sum,
        }
    }

    /// A distribution over `n` items in proportion to non-negative `weights` (negatives and NaN
    /// count as 0), for discrete sampling; `None` when there are none, or their sum is zero or
    /// not finite (nothing to pick from).
    pub fn from_weights(weights: &[f64]) -> Option<Distribution1D> {
        let total: f64 = weights.iter().map(|w| w.max(0.0)).sum();
        if weights.is_empty() || !(total > 0.0 && total.is_finite()) {
            return None;
        }
        Some(Distribution1D::new(weights))
    }

    /// The number of cdf entries ≤ `u` (`u` in [0, 1]): a binary search of the guide table's
    /// bracket (one slice wider on each side, so the rounding of `u · n` cannot matter).
    #[inline]
    fn count_at_most(&self, u: f64) -> usize {
        let n = self.func.len();
        let k = ((u * n as f64) as usize).min(n);
        let lo = self.guide[k.saturating_sub(1)] as usize;
        let hi = (self.guide[(k + 2).min(n)] as usize).min(self.cdf.len());
        lo + self.cdf[lo..hi].partition_point(|&c| c <= u)
    }

    /// The piece whose cdf interval holds `u` (clamped to [0, 1]): the last `i` with
    /// `cdf[i] <= u`, which has positive mass.
    #[inline]
    fn piece_at(&self, u: f64) -> usize {
        (self.count_at_most(u).max(1) - 1).min(self.func.len() - 1)
    }

    /// Number of pieces.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false (at least one piece).
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// `∫₀¹ f`.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// The value of piece `i` (0 for pieces given as NaN or negative).
    #[inline]
    pub fn value(&self, i: usize) -> f64 {
        self.func[i]
    }

    /// Maps `u ∈ [0, 1)` to `(x ∈ [0, 1), density at x, piece index)` (pbrt's
    /// `SampleContinuous`).
    pub fn sample(&self, u: f64) -> (f64, f64, usize) {
        let n = self.func.len();
        let u = u.clamp(0.0, 1.0);
        let i = self.piece_at(u);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.0
        };
        let x = ((i as f64 + du.clamp(0.0, 1.0)) / n as f64).min(1.0 - f64::EPSILON);
        (x, self.func[i] / self.integral, i)
    }

    /// Density at `x ∈ [0, 1)`.
    pub fn pdf(&self, x: f64) -> f64 {
        let n = self.func.len();
        let i = ((x * n as f64) as usize).min(n - 1);
        self.func[i] / self.integral
    }

    /// Picks an item for `u` in [0, 1): (index, probability) (pbrt's `SampleDiscrete`).
    #[inline]
    pub fn sample_discrete(&self, u: f64) -> (usize, f64) {
        let i = self.piece_at(u.clamp(0.0, 1.0));
        (i, self.pmf(i))
    }

    /// The probability of item `i` in discrete sampling: its value over the sum of the values
    /// (pbrt's `DiscretePDF`).
    #[inline]
    pub fn pmf(&self, i: usize) -> f64 {
        self.func[i] / self.sum
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
        let d = Distribution1D::from_weights(&[1.0, 0.0, 3.0]).unwrap();
        assert_eq!(d.sample_discrete(0.0), (0, 0.25));
        assert_eq!(d.sample_discrete(0.2499).0, 0);
        assert_eq!(d.sample_discrete(0.25).0, 2);
        assert_eq!(d.sample_discrete(0.999999).0, 2);
        assert_eq!(d.pmf(1), 0.0);
        assert!(Distribution1D::from_weights(&[0.0, 0.0]).is_none());
        assert!(Distribution1D::from_weights(&[f64::NAN]).is_none());
        assert!(Distribution1D::from_weights(&[]).is_none());
    }

    /// The guide table changes how the cdf is searched, not the inversion: every sample is the
    /// one a plain binary search of the whole table gives — on smooth, spiky, sparse and
    /// all-zero pieces, at piece boundaries and at the ends of [0, 1].
    #[test]
    fn guided_search_equals_binary_search() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let spiky: Vec<f64> = (0..1000)
            .map(|i| {
                if i % 97 == 3 {
                    1e6
                } else {
                    1e-3 * (i % 7) as f64
                }
            })
            .collect();
        let sparse: Vec<f64> = (0..333).map(|i| if i == 200 { 1.0 } else { 0.0 }).collect();
        let smooth: Vec<f64> = (0..1024).map(|i| (i as f64 * 0.01).sin().abs()).collect();
        for func in [spiky, sparse, smooth, vec![0.0; 17], vec![2.0]] {
            let d = Distribution1D::new(&func);
            let n = d.len();
            let plain = |u: f64| {
                let u = u.clamp(0.0, 1.0);
                (d.cdf.partition_point(|&c| c <= u).max(1) - 1).min(n - 1)
            };
            let mut us: Vec<f64> = (0..20000)
                .map(|_| rand::Rng::random::<f64>(&mut rng))
                .collect();
            us.extend(d.cdf.iter().flat_map(|&c| [c, c.next_down(), c.next_up()]));
            us.extend([0.0, 1.0, 1.0f64.next_down(), 0.5]);
            for u in us {
                assert_eq!(d.sample(u).2, plain(u), "u = {u}");
            }
        }
    }

    /// Discrete sampling through the one distribution picks what the lights' former discrete
    /// table (`cdf` = running sum of `w / Σw`, first entry above `u`) picked, with the same
    /// probability bit for bit, on random, sparse and power-of-two-free weights.
    #[test]
    fn discrete_sampling_matches_a_plain_pmf_table() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let mut r = || rand::Rng::random::<f64>(&mut rng);
        for n in [1usize, 2, 3, 7, 100, 1000] {
            let w: Vec<f64> = (0..n)
                .map(|i| if i % 5 == 1 { 0.0 } else { r() * 10.0 })
                .collect();
            let Some(d) = Distribution1D::from_weights(&w) else {
                continue;
            };
            let total: f64 = w.iter().map(|w| w.max(0.0)).sum();
            let pmf: Vec<f64> = w.iter().map(|w| w.max(0.0) / total).collect();
            let mut cdf: Vec<f64> = pmf
                .iter()
                .scan(0.0, |acc, p| {
                    *acc += p;
                    Some(*acc)
                })
                .collect();
            *cdf.last_mut().unwrap() = 1.0;
            for (i, p) in pmf.iter().enumerate() {
                assert_eq!(d.pmf(i).to_bits(), p.to_bits(), "n {n} item {i}");
            }
            for _ in 0..20000 {
                let u = r();
                let i = cdf.partition_point(|&c| c <= u).min(n - 1);
                assert_eq!(d.sample_discrete(u), (i, pmf[i]), "n {n} u {u}");
            }
        }
    }

    #[test]
    fn power_heuristic_limits() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-15);
        assert_eq!(power_heuristic(f64::INFINITY, 1.0), 1.0);
    }
}
