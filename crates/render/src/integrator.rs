//! The path tracer (book §9.8–9.11; pbrt-v4 `PathIntegrator`): next-event estimation on the
//! area lights and the environment combined with BRDF sampling by multiple importance
//! sampling (power heuristic), Russian roulette, a maximum depth.
//!
//! Depth counts scattering vertices: `max_depth = 3` gives direct lighting at the first three
//! hits and lets the ray leaving the third find an emitter — the book's "3 bounces" (its
//! `level`). Mitsuba's `max_depth` counts that last segment too: ours + 1.

use crate::environment::Environment;
use crate::math::{Frame, Rgb};
use crate::ray::{offset_origin, Ray};
use crate::sampling::power_heuristic;
use crate::world::{Surface, World};

/// Which estimators to combine (the two single-strategy modes exist to test MIS).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Strategy {
    /// Light sampling and BRDF sampling weighted by the power heuristic.
    #[default]
    Mis,
    /// BRDF sampling only (emitters found by chance), as in naive path tracing (§9.8).
    BrdfOnly,
    /// Light sampling only for direct light (the book's split of §9.10).
    LightOnly,
}

/// A source of uniform numbers in [0, 1).
pub trait Sampler {
    /// The next uniform number in [0, 1).
    fn next(&mut self) -> f64;
    /// Two numbers.
    #[inline]
    fn next2(&mut self) -> [f64; 2] {
        [self.next(), self.next()]
    }
}

/// Path-tracing settings.
#[derive(Clone, Copy)]
pub struct PathTracer<'a> {
    /// The scene.
    pub world: &'a World,
    /// Radiance at infinity.
    pub environment: &'a dyn Environment,
    /// Maximum number of scattering vertices.
    pub max_depth: u32,
    /// Russian roulette starts at this depth.
    pub rr_depth: u32,
    /// Estimator combination.
    pub strategy: Strategy,
}

impl PathTracer<'_> {
    /// Probability of sampling the environment rather than the area lights in NEE.
    #[inline]
    fn p_env(&self) -> f64 {
        match (self.world.lights.is_empty(), self.environment.is_black()) {
            (true, true) => 0.0,
            (true, false) => 1.0,
            (false, true) => 0.0,
            (false, false) => 0.5,
        }
    }

    /// The radiance arriving along `ray` (book eq. of §9.3 estimated as in §9.8).
    pub fn radiance(&self, mut ray: Ray, s: &mut impl Sampler) -> Rgb {
        let world = self.world;
        let env = self.environment;
        let p_env = self.p_env();
        let mut l = Rgb::BLACK;
        let mut beta = Rgb::WHITE;
        let mut specular = true;
        let mut prev_pdf = 0.0;
        let mut prev_p = ray.o;
        let mut depth = 0u32;
        loop {
            let Some(hit) = world.intersect(&ray, f64::INFINITY) else {
                let le = env.radiance(ray.d);
                if !le.is_black() {
                    let w = if specular || self.strategy == Strategy::BrdfOnly {
                        1.0
                    } else if self.strategy == Strategy::LightOnly {
                        0.0
                    } else {
                        power_heuristic(prev_pdf, p_env * env.pdf(ray.d))
                    };
                    l += beta * le * w;
                }
                break;
            };
            let m = match hit.surface {
                Surface::Emitter(i) => {
                    let le = world.emitted(i);
                    let w = if specular || self.strategy == Strategy::BrdfOnly {
                        1.0
                    } else if self.strategy == Strategy::LightOnly {
                        0.0
                    } else {
                        let lp = world.lights.pdf(i as usize, prev_p, hit.p, ray.d);
                        power_heuristic(prev_pdf, (1.0 - p_env) * lp)
                    };
                    l += beta * le * w;
                    break;
                }
                Surface::Material(m) => m,
            };
            if depth == self.max_depth {
                break;
            }
            depth += 1;
            // A textured material is modulated at the hit point; others are used in place.
            let textured;
            let brdf = match world.texture(m) {
                None => world.material(m),
                Some(t) => {
                    textured = world.material(m).with_diffuse_scaled(t.factor(hit.p));
                    &textured
                }
            };
            // Two-sided surfaces: shade with the normal facing the viewer (book's adjust_normal).
            let n = if hit.ng.dot(ray.d) > 0.0 {
                -hit.ng
            } else {
                hit.ng
            };
            let frame = Frame::from_normal(n);
            let wo = frame.to_local(-ray.d);
            if wo.z <= 0.0 {
                break;
            }
            // Next-event estimation.
            if !brdf.is_specular()
                && self.strategy != Strategy::BrdfOnly
                && (p_env > 0.0 || !world.lights.is_empty())
            {
                let uc = s.next();
                let u = s.next2();
                let u_light = s.next();
                let sample = if uc < p_env {
                    env.sample(u)
                        .map(|e| (e.wi, e.radiance, f64::INFINITY, e.pdf_solid_angle * p_env))
                } else {
                    world.lights.sample(hit.p, u_light, u).map(|ls| {
                        (
                            ls.wi,
                            ls.radiance,
                            ls.distance,
                            ls.pdf_solid_angle * (1.0 - p_env),
                        )
                    })
                };
                if let Some((wi, le, dist, pdf)) = sample {
                    let cos = wi.dot(n);
                    if cos > 0.0 && pdf > 0.0 && !le.is_black() {
                        let wil = frame.to_local(wi);
                        let f = brdf.eval(wo, wil);
                        if !f.is_black() {
                            let o = offset_origin(hit.p, hit.ng, wi);
                            let t_max = if dist.is_finite() {
                                // Stop short of the light's surface.
                                (dist - (o - hit.p).length()) * (1.0 - 1e-9)
                            } else {
                                f64::INFINITY
                            };
                            if !world.occluded(&Ray::new(o, wi), t_max) {
                                let w = if self.strategy == Strategy::LightOnly {
                                    1.0
                                } else {
                                    power_heuristic(pdf, brdf.pdf(wo, wil))
                                };
                                l += beta * f * le * (cos * w / pdf);
                            }
                        }
                    }
                }
            }
            // BRDF sampling.
            let u = s.next2();
            let uc = s.next();
            let Some(bs) = brdf.sample(wo, u, uc) else {
                break;
            };
            if bs.f.is_black() || bs.wi.z <= 0.0 {
                break;
            }
            beta *= bs.f * (bs.wi.z / bs.pdf);
            specular = bs.specular;
            prev_pdf = bs.pdf;
            prev_p = hit.p;
            let wi = frame.to_world(bs.wi);
            ray = Ray::new(offset_origin(hit.p, hit.ng, wi), wi);
            // Russian roulette on the throughput's largest component (pbrt-v4): a path whose
            // throughput fell below 1 survives with that probability and is reweighted.
            let q = beta.max_component();
            if depth >= self.rr_depth && q < 1.0 {
                if q <= 0.0 || s.next() >= q {
                    break;
                }
                beta *= 1.0 / q;
            }
        }
        l
    }
}
