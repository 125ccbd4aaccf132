//! The path tracer (book §9.8–9.11; pbrt-v4 `PathIntegrator`): next-event estimation on the
//! area lights and the environment combined with BRDF sampling by multiple importance
//! sampling (power heuristic), Russian roulette, a maximum depth.
//!
//! Depth counts scattering vertices: `max_depth = 3` gives direct lighting at the first three
//! hits and lets the ray leaving the third find an emitter — the book's "3 bounces" (its
//! `level`). Mitsuba's `max_depth` counts that last segment too: ours + 1.

use crate::environment::Environment;
use crate::math::Vec3;
use crate::math::{Frame, Rgb};
use crate::ray::{offset_origin, Ray};
use crate::sampling::power_heuristic;
use crate::world::{Surface, SurfaceHit, World};

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

/// A source of uniform numbers in [0, 1); a clone continues the same stream (correlated
/// sampling forks a path's stream where two estimates part).
pub trait Sampler: Clone {
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
    pub fn radiance(&self, ray: Ray, s: &mut impl Sampler) -> Rgb {
        self.trace(
            ray,
            PathState::camera(&ray),
            s,
            None,
            (Rgb::BLACK, Rgb::BLACK),
        )
        .0
    }

    /// The radiance along `ray` in this tracer's world *and* in `without`, the same world less
    /// its synthetic objects (`is_synthetic(m)` for material `m` of this world), from the same
    /// random numbers — the two estimates of differential rendering (book §10.10) with
    /// correlated sampling. `without` must hold exactly this world's non-synthetic geometry.
    ///
    /// The two paths are one path until it meets a synthetic object: every vertex before that is
    /// shared (one intersection, one light sample, one BRDF sample); a light sample blocked in
    /// this world is tested again in `without`, where only the synthetic objects may be missing.
    /// Where a segment first meets a synthetic object the paths part, each continuing from a copy
    /// of the random stream. The result equals two separate [`PathTracer::radiance`] calls with
    /// clones of `s`, bit for bit, at about the cost of one wherever the objects do not matter.
    pub fn radiance_with_and_without<S: Sampler>(
        &self,
        without: &World,
        is_synthetic: &dyn Fn(u32) -> bool,
        ray: Ray,
        s: &mut S,
    ) -> (Rgb, Rgb) {
        self.trace(
            ray,
            PathState::camera(&ray),
            s,
            Some((without, is_synthetic)),
            (Rgb::BLACK, Rgb::BLACK),
        )
    }

    /// The path loop from `ray` with the throughput and MIS state of `st`, adding to the
    /// radiance `sums` gathered so far (this world's, the twin's); with `twin`, also the twin
    /// world's path (see [`PathTracer::radiance_with_and_without`]).
    fn trace<S: Sampler>(
        &self,
        mut ray: Ray,
        mut st: PathState,
        s: &mut S,
        twin: Option<Twin<'_>>,
        sums: (Rgb, Rgb),
    ) -> (Rgb, Rgb) {
        let world = self.world;
        let env = self.environment;
        let p_env = self.p_env();
        // While the paths agree, every term is added to both.
        let (mut l, mut lo) = sums;
        loop {
            let Some(hit) = world.intersect(&ray, f64::INFINITY) else {
                let mis = !(st.specular || self.strategy == Strategy::BrdfOnly);
                let (le, pdf) = if mis && self.strategy == Strategy::Mis {
                    env.radiance_and_pdf(ray.d)
                } else {
                    (env.radiance(ray.d), 0.0)
                };
                if !le.is_black() {
                    let w = if !mis {
                        1.0
                    } else if self.strategy == Strategy::LightOnly {
                        0.0
                    } else {
                        power_heuristic(st.prev_pdf, p_env * pdf)
                    };
                    l += st.beta * le * w;
                    lo += st.beta * le * w;
                }
                break;
            };
            let m = match hit.surface {
                Surface::Emitter(i) => {
                    let le = world.emitted(i);
                    let w = if st.specular || self.strategy == Strategy::BrdfOnly {
                        1.0
                    } else if self.strategy == Strategy::LightOnly {
                        0.0
                    } else {
                        let lp = world.lights.pdf(i as usize, st.prev_p, hit.p, ray.d);
                        power_heuristic(st.prev_pdf, (1.0 - p_env) * lp)
                    };
                    l += st.beta * le * w;
                    lo += st.beta * le * w;
                    break;
                }
                Surface::Material(m) => m,
            };
            if let Some((without, is_synthetic)) = twin {
                if is_synthetic(m) {
                    // The paths part here: each world continues along this ray from its own
                    // copy of the random stream.
                    let twin_tracer = PathTracer {
                        world: without,
                        ..*self
                    };
                    let mut s2 = s.clone();
                    let lo = twin_tracer
                        .trace(ray, st, &mut s2, None, (lo, Rgb::BLACK))
                        .0;
                    let l = self.trace_from_hit(ray, hit, m, st, s, l);
                    return (l, lo);
                }
            }
            match self.scatter(&mut ray, &hit, m, &mut st, s, twin) {
                Scatter::Continue(add, add_twin) => {
                    l += add;
                    lo += add_twin;
                }
                Scatter::Stop(add, add_twin) => {
                    l += add;
                    lo += add_twin;
                    break;
                }
            }
        }
        (l, lo)
    }

    /// The path loop resumed at a hit already found on material `m` (no twin), adding to `l`.
    fn trace_from_hit<S: Sampler>(
        &self,
        mut ray: Ray,
        hit: SurfaceHit,
        m: u32,
        mut st: PathState,
        s: &mut S,
        l: Rgb,
    ) -> Rgb {
        match self.scatter(&mut ray, &hit, m, &mut st, s, None) {
            Scatter::Continue(add, _) => self.trace(ray, st, s, None, (l + add, Rgb::BLACK)).0,
            Scatter::Stop(add, _) => l + add,
        }
    }

    /// One scattering vertex at `hit` on material `m`: the light sample (next-event estimation)
    /// and the BRDF sample that sets the next `ray`. Returns the radiance it adds (and the
    /// twin's, when a blocked light sample is clear in the twin world) and whether the path
    /// goes on.
    fn scatter<S: Sampler>(
        &self,
        ray: &mut Ray,
        hit: &SurfaceHit,
        m: u32,
        st: &mut PathState,
        s: &mut S,
        twin: Option<Twin<'_>>,
    ) -> Scatter {
        let world = self.world;
        let env = self.environment;
        let p_env = self.p_env();
        let mut add = Rgb::BLACK;
        let mut add_twin = Rgb::BLACK;
        if st.depth == self.max_depth {
            return Scatter::Stop(add, add_twin);
        }
        st.depth += 1;
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
            return Scatter::Stop(add, add_twin);
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
                        let shadow = Ray::new(o, wi);
                        // The twin world lacks only synthetic objects: what is clear here is
                        // clear there.
                        let (clear, clear_twin) = if !world.occluded(&shadow, t_max) {
                            (true, true)
                        } else {
                            (
                                false,
                                twin.is_some_and(|(without, _)| !without.occluded(&shadow, t_max)),
                            )
                        };
                        if clear || clear_twin {
                            let w = if self.strategy == Strategy::LightOnly {
                                1.0
                            } else {
                                power_heuristic(pdf, brdf.pdf(wo, wil))
                            };
                            let c = st.beta * f * le * (cos * w / pdf);
                            if clear {
                                add += c;
                            }
                            if clear_twin {
                                add_twin += c;
                            }
                        }
                    }
                }
            }
        }
        // BRDF sampling.
        let u = s.next2();
        let uc = s.next();
        let Some(bs) = brdf.sample(wo, u, uc) else {
            return Scatter::Stop(add, add_twin);
        };
        if bs.f.is_black() || bs.wi.z <= 0.0 {
            return Scatter::Stop(add, add_twin);
        }
        st.beta *= bs.f * (bs.wi.z / bs.pdf);
        st.specular = bs.specular;
        st.prev_pdf = bs.pdf;
        st.prev_p = hit.p;
        let wi = frame.to_world(bs.wi);
        *ray = Ray::new(offset_origin(hit.p, hit.ng, wi), wi);
        // Russian roulette on the throughput's largest component (pbrt-v4): a path whose
        // throughput fell below 1 survives with that probability and is reweighted.
        let q = st.beta.max_component();
        if st.depth >= self.rr_depth && q < 1.0 {
            if q <= 0.0 || s.next() >= q {
                return Scatter::Stop(add, add_twin);
            }
            st.beta *= 1.0 / q;
        }
        Scatter::Continue(add, add_twin)
    }
}

/// The twin world of [`PathTracer::radiance_with_and_without`] and its test for synthetic
/// materials.
type Twin<'a> = (&'a World, &'a dyn Fn(u32) -> bool);

/// What a path carries from vertex to vertex.
#[derive(Clone, Copy, Debug)]
struct PathState {
    /// Throughput.
    beta: Rgb,
    /// The last bounce was specular (or this is the camera ray): emitters count fully.
    specular: bool,
    /// Solid-angle pdf of the last BRDF sample (for MIS at emitters).
    prev_pdf: f64,
    /// The last vertex (for the area-light pdf).
    prev_p: Vec3,
    /// Scattering vertices so far.
    depth: u32,
}

impl PathState {
    /// The state of a path starting with `ray`.
    fn camera(ray: &Ray) -> PathState {
        PathState {
            beta: Rgb::WHITE,
            specular: true,
            prev_pdf: 0.0,
            prev_p: ray.o,
            depth: 0,
        }
    }
}

/// A vertex's outcome: the radiance it adds (here, in the twin world) and whether the path
/// goes on.
enum Scatter {
    Continue(Rgb, Rgb),
    Stop(Rgb, Rgb),
}
