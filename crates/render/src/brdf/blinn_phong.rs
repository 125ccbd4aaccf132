//! The modified Blinn–Phong BRDF (book §9.5.3) made energy conserving:
//!
//! f(wo, wi) = ρd/π + ρs · C(e) · (n·h)^e,   h = (wo + wi)/|wo + wi|,
//! C(e) = (e + 2)(e + 4) / (8π (e + 2^(−e/2))).
//!
//! C(e) makes the lobe's directional albedo ∫ C (n·h)^e cos θi dωi exactly 1 at normal
//! incidence, where it is largest (it falls off towards grazing angles); so ρd + ρs ≤ 1
//! guarantees energy conservation (tested numerically). The book's code uses
//! kd·d_col + ks·(n·h)^se without these factors. The BRDF is symmetric in (wo, wi), hence
//! reciprocal. Sampling: pick the diffuse lobe with probability ∝ luminance of ρd, else
//! the half vector from pdf_h = (e+1)/(2π) cos^e θh and reflect wo about it
//! (pdf_wi = pdf_h / (4 wo·h)); `pdf` is the mixture (pbrt-v3 §14.1 on microfacet sampling).

use std::f64::consts::{FRAC_1_PI, PI};

use serde::{Deserialize, Serialize};

use super::BrdfSample;
use crate::math::{Rgb, Vec3};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// Diffuse + normalized Blinn–Phong lobe (book §9.5.3). Keep ρd + ρs ≤ 1 per channel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlinnPhong {
    /// Diffuse albedo ρd.
    pub diffuse: Rgb,
    /// Specular albedo ρs (the lobe's albedo at normal incidence).
    pub specular: Rgb,
    /// Exponent e ≥ 0 of (n·h)^e.
    pub exponent: f64,
}

impl BlinnPhong {
    /// The normalization C(e) of the lobe.
    #[inline]
    pub fn normalization(e: f64) -> f64 {
        (e + 2.0) * (e + 4.0) / (8.0 * PI * (e + (-e / 2.0).exp2()))
    }

    #[inline]
    fn p_diffuse(&self) -> f64 {
        let (d, s) = (self.diffuse.luminance(), self.specular.luminance());
        if d + s <= 0.0 {
            0.0
        } else {
            d / (d + s)
        }
    }

    /// f(wo, wi).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let h = wo + wi;
        let len = h.length();
        let cos_h = if len > 0.0 { (h.z / len).max(0.0) } else { 0.0 };
        self.diffuse * FRAC_1_PI
            + self.specular * (Self::normalization(self.exponent) * cos_h.powf(self.exponent))
    }

    /// Density of the half-vector sampling, in solid angle of wi.
    #[inline]
    fn spec_pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        let h = wo + wi;
        let len = h.length();
        if len == 0.0 {
            return 0.0;
        }
        let h = h / len;
        let (cos_h, wo_h) = (h.z, wo.dot(h));
        if cos_h <= 0.0 || wo_h <= 0.0 {
            return 0.0;
        }
        let e = self.exponent;
        (e + 1.0) / (2.0 * PI) * cos_h.powf(e) / (4.0 * wo_h)
    }

    /// Samples the mixture of the two lobes.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let pd = self.p_diffuse();
        if self.diffuse.is_black() && self.specular.is_black() {
            return None;
        }
        let wi = if uc < pd {
            cosine_hemisphere(u).0
        } else {
            let e = self.exponent;
            let cos_h = u[0].powf(1.0 / (e + 1.0));
            let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
            let phi = 2.0 * PI * u[1];
            let h = Vec3::new(sin_h * phi.cos(), sin_h * phi.sin(), cos_h);
            let wo_h = wo.dot(h);
            if wo_h <= 0.0 {
                return None;
            }
            h * (2.0 * wo_h) - wo
        };
        let pdf = self.pdf(wo, wi);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        Some(BrdfSample {
            wi,
            f: self.eval(wo, wi),
            pdf,
            specular: false,
        })
    }

    /// The mixture density.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        let pd = self.p_diffuse();
        pd * cosine_hemisphere_pdf(wi) + (1.0 - pd) * self.spec_pdf(wo, wi)
    }
}
