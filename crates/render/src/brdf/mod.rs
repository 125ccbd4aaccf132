//! BRDFs of book §9.5 with importance sampling (pbrt-v4 `BxDF`: `eval`, `sample`, `pdf`).
//!
//! Everything here works in the local shading frame: the normal is +z and `wo` (towards the
//! viewer) has `wo.z > 0` — the integrator flips the normal to the side of the incoming ray,
//! as the book's `adjust_normal` does, so every surface is two-sided. Directions point away
//! from the surface. Pdfs are in solid angle.

mod blinn_phong;
mod lambert;
mod mirror;

pub use blinn_phong::BlinnPhong;
pub use lambert::Lambert;
pub use mirror::Mirror;

use serde::{Deserialize, Serialize};

use crate::math::{Rgb, Vec3};

/// A sampled incident direction (pbrt-v4 `BSDFSample`).
#[derive(Clone, Copy, Debug)]
pub struct BrdfSample {
    /// Incident direction, local frame, unit.
    pub wi: Vec3,
    /// BRDF value f(wo, wi) (for a specular sample: the reflectance divided by |cos θi|, so
    /// f·|cos θi|/pdf is the reflectance).
    pub f: Rgb,
    /// Pdf in solid angle (1 for a specular sample, which is a Dirac delta).
    pub pdf: f64,
    /// True for a Dirac-delta sample (no MIS, no NEE).
    pub specular: bool,
}

/// The materials of the book (§9.5): Lambertian, perfect mirror, and the modified
/// Blinn–Phong, normalized to conserve energy.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Brdf {
    /// Perfect diffuse reflector (§9.5.1).
    Lambert(Lambert),
    /// Perfect mirror (§9.5.2).
    Mirror(Mirror),
    /// Diffuse plus a normalized (n·h)^e lobe (§9.5.3).
    BlinnPhong(BlinnPhong),
}

impl Brdf {
    /// f(wo, wi); zero when either direction is below the surface or for a Dirac delta.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match self {
            Brdf::Lambert(b) => b.eval(wo, wi),
            Brdf::Mirror(_) => Rgb::BLACK,
            Brdf::BlinnPhong(b) => b.eval(wo, wi),
        }
    }
    /// Samples wi given wo, with `u` uniform in [0,1)² and `uc` uniform in [0,1) (lobe choice).
    /// `None` when no direction could be generated (the sample carries no energy).
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f64; 2], uc: f64) -> Option<BrdfSample> {
        match self {
            Brdf::Lambert(b) => b.sample(wo, u),
            Brdf::Mirror(b) => b.sample(wo),
            Brdf::BlinnPhong(b) => b.sample(wo, u, uc),
        }
    }
    /// The solid-angle density with which [`Brdf::sample`] generates wi (0 for a delta).
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        match self {
            Brdf::Lambert(b) => b.pdf(wo, wi),
            Brdf::Mirror(_) => 0.0,
            Brdf::BlinnPhong(b) => b.pdf(wo, wi),
        }
    }
    /// This BRDF with its diffuse albedo multiplied by `factor` (a texture's value at the
    /// hit point, [`crate::texture`]); a mirror has no diffuse part and is returned unchanged.
    #[inline]
    pub fn with_diffuse_scaled(&self, factor: Rgb) -> Brdf {
        match *self {
            Brdf::Lambert(b) => Brdf::Lambert(Lambert {
                albedo: b.albedo * factor,
            }),
            Brdf::Mirror(m) => Brdf::Mirror(m),
            Brdf::BlinnPhong(b) => Brdf::BlinnPhong(BlinnPhong {
                diffuse: b.diffuse * factor,
                ..b
            }),
        }
    }
    /// True when the BRDF is a Dirac delta (next-event estimation is pointless).
    #[inline]
    pub fn is_specular(&self) -> bool {
        matches!(self, Brdf::Mirror(_))
    }
}

#[cfg(test)]
mod tests;
