//! What a path sees when it leaves the scene: the light dome (book §10, image-based lighting)
//! behind a small interface, so the HDR dome can plug in. Pdfs are in solid angle (pbrt-v4
//! `Light::SampleLi` / `PDF_Li` for infinite lights).

use std::f64::consts::FRAC_1_PI;

use crate::math::{Rgb, Vec3};
use crate::sampling::uniform_sphere;

/// A sampled direction towards the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentSample {
    /// Unit direction towards the environment (world frame).
    pub wi: Vec3,
    /// Radiance arriving along −wi.
    pub radiance: Rgb,
    /// Pdf in solid angle.
    pub pdf_solid_angle: f64,
}

/// Radiance at infinity, importance-sampled (book §10: paths that escape take the dome's
/// radiance). `dir` is a unit world direction pointing away from the scene.
pub trait Environment: Send + Sync {
    /// Radiance arriving from direction `dir`.
    fn radiance(&self, dir: Vec3) -> Rgb;
    /// A direction sampled with `u` in [0,1)², its radiance and its solid-angle pdf; `None`
    /// if nothing can be sampled.
    fn sample(&self, u: [f64; 2]) -> Option<EnvironmentSample>;
    /// The solid-angle density of [`Environment::sample`] at `dir`.
    fn pdf(&self, dir: Vec3) -> f64;
    /// [`Environment::radiance`] and [`Environment::pdf`] of one direction (an escaped path
    /// weighed by MIS needs both; an environment can share the work).
    fn radiance_and_pdf(&self, dir: Vec3) -> (Rgb, f64) {
        (self.radiance(dir), self.pdf(dir))
    }
    /// True when the environment is black everywhere (no sampling needed).
    fn is_black(&self) -> bool {
        false
    }
}

/// A uniform environment of constant radiance (a white furnace when the scene is white),
/// sampled uniformly over the sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstantEnvironment {
    /// The radiance from every direction.
    pub radiance: Rgb,
}

impl Environment for ConstantEnvironment {
    fn radiance(&self, _dir: Vec3) -> Rgb {
        self.radiance
    }
    fn sample(&self, u: [f64; 2]) -> Option<EnvironmentSample> {
        if self.radiance.is_black() {
            return None;
        }
        let (wi, pdf) = uniform_sphere(u);
        Some(EnvironmentSample {
            wi,
            radiance: self.radiance,
            pdf_solid_angle: pdf,
        })
    }
    fn pdf(&self, _dir: Vec3) -> f64 {
        if self.radiance.is_black() {
            0.0
        } else {
            0.25 * FRAC_1_PI
        }
    }
    fn is_black(&self) -> bool {
        self.radiance.is_black()
    }
}
