//! The perfect Lambertian BRDF f = ρ/π (book §9.5.1), sampled cosine-weighted.

use std::f64::consts::FRAC_1_PI;

use serde::{Deserialize, Serialize};

use super::BrdfSample;
use crate::math::{Rgb, Vec3};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// Lambertian reflector with albedo ρ ∈ [0, 1]³ (book §9.5.1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lambert {
    /// Albedo ρ: the fraction of irradiance reflected.
    pub albedo: Rgb,
}

impl Lambert {
    /// f = ρ/π above the surface.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        self.albedo * FRAC_1_PI
    }
    /// Cosine-weighted sample, pdf cos θ/π.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f64; 2]) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let (wi, pdf) = cosine_hemisphere(u);
        if pdf <= 0.0 {
            return None;
        }
        Some(BrdfSample {
            wi,
            f: self.albedo * FRAC_1_PI,
            pdf,
            specular: false,
        })
    }
    /// cos θi/π.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        cosine_hemisphere_pdf(wi)
    }
}
