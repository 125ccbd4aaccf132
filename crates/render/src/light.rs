//! Polygonal area lights sampled by area (book §9.11; pbrt-v4 `DiffuseAreaLight`), with the
//! pdf converted to solid angle for multiple importance sampling, or by the solid angle each
//! triangle subtends ([`crate::spherical_triangle`], Arvo 1995).

use crate::math::{Rgb, Vec3};
use crate::sampling::{uniform_triangle, Distribution1D};
use crate::shape::Triangle;
use crate::spherical_triangle;

/// How a point on a light triangle is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum LightSampling {
    /// Uniformly by area (book §9.11); pdf converted to solid angle.
    #[default]
    Area,
    /// Uniformly in the solid angle the triangle subtends (Arvo 1995), falling back to area
    /// sampling when that solid angle is below 3·10⁻⁴ sr or above 6.22 sr (where the
    /// spherical construction loses precision; pbrt-v4's thresholds). The choice depends only
    /// on the shading point, so [`LightSet::pdf`] makes the same one.
    SolidAngle,
}

const MIN_SPHERICAL: f64 = 3e-4;
const MAX_SPHERICAL: f64 = 6.22;

/// A light sample seen from a shading point (pbrt-v4's `LightLiSample`, ch. 12).
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Emitted radiance towards the shading point.
    pub radiance: Rgb,
    /// Unit direction from the shading point to the light point.
    pub wi: Vec3,
    /// Distance to the light point.
    pub distance: f64,
    /// Pdf in solid angle at the shading point (including the choice of the triangle).
    pub pdf_solid_angle: f64,
}

/// All emitting triangles of a scene; a triangle is chosen with probability ∝ its power
/// (area × luminance), then a point uniformly on it. Emission is two-sided, as in the book.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    tris: Vec<Triangle>,
    radiance: Vec<Rgb>,
    dist: Option<Distribution1D>,
    mode: LightSampling,
}

impl LightSet {
    /// From (triangle, radiance) pairs.
    pub fn new(items: Vec<(Triangle, Rgb)>) -> LightSet {
        let weights: Vec<f64> = items
            .iter()
            .map(|(t, l)| t.area * l.luminance().max(l.max_component() * 1e-3))
            .collect();
        let dist = Distribution1D::from_weights(&weights);
        let (tris, radiance) = items.into_iter().unzip();
        LightSet {
            tris,
            radiance,
            dist,
            mode: LightSampling::Area,
        }
    }
    /// The same lights sampled with `mode`.
    pub fn with_sampling(mut self, mode: LightSampling) -> LightSet {
        self.mode = mode;
        self
    }
    /// The sampling mode.
    pub fn sampling(&self) -> LightSampling {
        self.mode
    }
    /// The solid angle of triangle `i` from `p` when it is sampled by solid angle, else `None`.
    #[inline]
    fn spherical(&self, i: usize, p: Vec3) -> Option<(f64, [Vec3; 3])> {
        if self.mode != LightSampling::SolidAngle {
            return None;
        }
        let t = &self.tris[i];
        let v = [t.p0, t.p0 + t.e1, t.p0 + t.e2];
        let o = spherical_triangle::solid_angle(p, v[0], v[1], v[2]);
        (o > MIN_SPHERICAL && o < MAX_SPHERICAL).then_some((o, v))
    }
    /// True when there is nothing to sample.
    pub fn is_empty(&self) -> bool {
        self.dist.is_none()
    }
    /// Number of emitting triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }
    /// Radiance of light triangle `i`.
    #[inline]
    pub fn radiance(&self, i: usize) -> Rgb {
        self.radiance[i]
    }
    /// Total emitted power Σ π·A·L (two faces: ×2), luminance.
    pub fn power(&self) -> f64 {
        self.tris
            .iter()
            .zip(&self.radiance)
            .map(|(t, l)| 2.0 * std::f64::consts::PI * t.area * l.luminance())
            .sum()
    }
    /// Samples a point on the lights as seen from `p`: `uc` picks the triangle, `u` the point.
    #[inline]
    pub fn sample(&self, p: Vec3, uc: f64, u: [f64; 2]) -> Option<LightSample> {
        let dist = self.dist.as_ref()?;
        let (i, pmf) = dist.sample_discrete(uc);
        let tri = &self.tris[i];
        if let Some((_, v)) = self.spherical(i, p) {
            let (wi, pdf) = spherical_triangle::sample(p, v, u)?;
            // Distance along wi to the triangle's plane.
            let den = tri.n.dot(wi);
            if den == 0.0 {
                return None;
            }
            let distance = tri.n.dot(tri.p0 - p) / den;
            if !(distance > 0.0 && distance.is_finite()) {
                return None;
            }
            return Some(LightSample {
                radiance: self.radiance[i],
                wi,
                distance,
                pdf_solid_angle: pmf * pdf,
            });
        }
        let b = uniform_triangle(u);
        let q = tri.point(b[1], b[2]);
        let d = q - p;
        let dist2 = d.length_squared();
        let distance = dist2.sqrt();
        if distance == 0.0 || !distance.is_finite() {
            return None;
        }
        let wi = d / distance;
        let cos_l = tri.n.dot(wi).abs();
        if cos_l <= 0.0 {
            return None;
        }
        Some(LightSample {
            radiance: self.radiance[i],
            wi,
            distance,
            pdf_solid_angle: pmf * dist2 / (tri.area * cos_l),
        })
    }
    /// The solid-angle pdf with which [`LightSet::sample`] from `p` would pick the point `q` of
    /// light triangle `i`, reached along unit direction `wi`.
    #[inline]
    pub fn pdf(&self, i: usize, p: Vec3, q: Vec3, wi: Vec3) -> f64 {
        let Some(dist) = self.dist.as_ref() else {
            return 0.0;
        };
        if let Some((o, _)) = self.spherical(i, p) {
            return dist.pmf(i) / o;
        }
        let tri = &self.tris[i];
        let cos_l = tri.n.dot(wi).abs();
        if cos_l <= 0.0 {
            return 0.0;
        }
        dist.pmf(i) * (q - p).length_squared() / (tri.area * cos_l)
    }
}
