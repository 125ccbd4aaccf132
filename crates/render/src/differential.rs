//! Differential rendering (book §10.10; Debevec, "Rendering synthetic objects into real
//! scenes", SIGGRAPH 1998): synthetic objects and the light they take from and give to a
//! *local scene* (the shadow catchers standing for the real ground) composited over a plate.
//!
//! Every pixel sample's camera ray is classified by what it meets first in the scene with the
//! objects:
//!
//! - a synthetic object → its path-traced radiance (the CG beauty, with coverage as alpha);
//! - a shadow catcher → the catcher rendered *with* the objects (W) and *without* them (Wo),
//!   both from the same random numbers (correlated sampling: paths that never meet an object
//!   give identical radiance, so the difference W − Wo is exactly zero away from shadows and
//!   reflections and its noise is the noise of the change only);
//! - nothing → the plate.
//!
//! With a pixel's coverages a_o (objects) and a_c (catchers), the premultiplied beauty B and
//! the catcher sums W and Wo (all divided by the sample count), the composite is
//!
//! - additive (Debevec 1998):  C = B + (1 − a_o)·P + (W − Wo)
//! - ratio (Cycles' shadow catcher): C = B + a_c·P·W/Wo + (1 − a_o − a_c)·P
//!
//! (evaluated as B + (1 − a_o)·P + a_c·P·(W/Wo − 1), so a pixel nothing changed is the plate
//! bit for bit)
//!
//! so the layers of [`DifferentialLayers`] are all a compositor needs (see [`composite`]).
//! Only pixels where some geometry can be seen are traced: a cheap pre-pass casts rays
//! through every pixel's corners and centre and traces a pixel when it or a neighbour saw
//! geometry; the rest of the frame is the plate, untouched.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use vfxgraph_imaging::Image;

use crate::camera::{Camera, ImageSize};
use crate::environment::Environment;
use crate::integrator::{PathTracer, Sampler, Strategy};
use crate::math::Rgb;
use crate::render::{mix_seed, PixelSampler, RenderError, RenderSettings};
use crate::scene::Scene;
use crate::world::{Surface, World};

/// How the catcher's change is applied to the plate (book §10.10).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, vfxgraph_params::Choice)]
pub enum CompositeMode {
    /// plate + (with − without): Debevec 1998, the book's program.
    #[default]
    Additive,
    /// plate × with / without: a multiplicative shadow matte (Cycles' shadow catcher); never
    /// darker than black, and it keeps the plate's texture inside shadows.
    Ratio,
}

/// The maximum scattering vertices per path of the shot's renders (the book's shot used 2
/// bounces): `fit_catcher`'s and `differential_render`'s default.
pub const SHOT_MAX_DEPTH: u32 = 2;

/// How a differential render samples: the estimators the shot offers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum ShotStrategy {
    /// Light/dome and BRDF sampling combined ([`Strategy::Mis`]).
    #[default]
    Mis,
    /// Hemisphere (BRDF) sampling only, as the book's program ([`Strategy::BrdfOnly`]).
    BrdfOnly,
}

impl From<ShotStrategy> for Strategy {
    fn from(s: ShotStrategy) -> Strategy {
        match s {
            ShotStrategy::Mis => Strategy::Mis,
            ShotStrategy::BrdfOnly => Strategy::BrdfOnly,
        }
    }
}

/// The `differential_render` node's options.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct DifferentialOptions {
    /// samples (paths) per pixel
    #[param(range = 1..=(1 << 20))]
    pub spp: u32,
    /// adaptive sampling: every traced pixel gets `min_spp` samples, then batches of `min_spp` more (up to `spp`) while its noise is above the `noise` target scaled by its samples / `min_spp` (samples in proportion to each pixel's deviation: the least total squared error for the samples spent); 0 = `spp` everywhere
    #[param(range = 0..=(1 << 20))]
    pub min_spp: u32,
    /// adaptive target: the standard error of a pixel's added light after `min_spp` samples, relative to the frame's mean rendered radiance
    #[param(range = 0.0..=10.0)]
    pub noise: f64,
    /// maximum scattering vertices per path (the book's shot used 2 bounces)
    #[param(range = 0..=1024)]
    pub max_depth: u32,
    /// extra seed mixed into the graph seed
    pub seed: u64,
    /// `additive`: plate + (with − without), Debevec 1998, the book; `ratio`: plate × with / without, a multiplicative shadow matte (keeps the plate's texture in shadows, never below black)
    pub mode: CompositeMode,
    /// `mis`: light/dome and BRDF sampling combined; `brdf_only`: hemisphere sampling only, as the book's program (for noise comparisons)
    pub strategy: ShotStrategy,
    /// a plate file pattern (e.g. plate/frame.%04d.exr), read when the `plate` input is not connected; empty = no plate
    #[param(path = "input")]
    pub plate: String,
    #[param(flatten)]
    pub size: ImageSize,
}

impl Default for DifferentialOptions {
    fn default() -> Self {
        DifferentialOptions {
            spp: RenderSettings::default().spp,
            min_spp: 0,
            noise: 0.01,
            max_depth: SHOT_MAX_DEPTH,
            seed: 0,
            mode: CompositeMode::Additive,
            strategy: ShotStrategy::Mis,
            plate: String::new(),
            size: ImageSize::default(),
        }
    }
}

impl DifferentialOptions {
    /// The renders' settings, seeded by `graph_seed` mixed with `seed`.
    pub fn settings(&self, graph_seed: u64) -> RenderSettings {
        RenderSettings {
            spp: self.spp,
            max_depth: self.max_depth,
            seed: mix_seed(graph_seed, self.seed),
            strategy: self.strategy.into(),
            ..Default::default()
        }
    }

    /// Adaptive sampling, when `min_spp` is set.
    pub fn adaptive(&self) -> Option<Adaptive> {
        (self.min_spp > 0).then_some(Adaptive {
            min_spp: self.min_spp,
            noise: self.noise,
        })
    }
}

/// The `composite` node's options: the mode and the plate (a file, else a constant grey).
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct CompositeOptions {
    /// `additive` (Debevec 1998, the book) or `ratio` (a multiplicative shadow matte)
    pub mode: CompositeMode,
    /// a plate file pattern, read when the `plate` input is not connected
    #[param(path = "input")]
    pub plate: String,
    /// the stand-in plate's radiance when there is no plate
    #[param(range = 0.0..=1e6)]
    pub grey: f64,
}

impl Default for CompositeOptions {
    fn default() -> Self {
        CompositeOptions {
            mode: CompositeMode::Additive,
            plate: String::new(),
            grey: 0.18,
        }
    }
}

/// The layers of a differential render, all linear RGB(A), premultiplied by coverage.
#[derive(Clone, Debug)]
pub struct DifferentialLayers {
    /// The synthetic objects' radiance; alpha = the fraction of the pixel they cover.
    pub beauty: Image,
    /// The catchers rendered with the objects present; alpha = the catchers' coverage.
    pub catcher_with: Image,
    /// The catchers rendered without the objects (the empty local scene); alpha as above.
    pub catcher_without: Image,
    /// Per-pixel variance of the beauty + (with − without) estimate (the noise of what the
    /// composite adds to the plate), RGB.
    pub variance: Image,
    /// Samples taken per pixel (0 where nothing was traced), one channel.
    pub samples: Image,
}

impl DifferentialLayers {
    /// The shadow/light matte: with / without over the catchers (1 where nothing changed or no
    /// catcher is seen), RGB — multiply the plate by it to add the shadows.
    pub fn shadow_ratio(&self) -> Image {
        let (w, h) = (self.beauty.width, self.beauty.height);
        Image::from_fn(w, h, 3, |x, y, c| {
            ratio(
                self.catcher_with.get(x, y, c),
                self.catcher_without.get(x, y, c),
            )
        })
    }

    /// The additive light change: with − without over the catchers (negative in shadows), RGB.
    pub fn shadow_difference(&self) -> Image {
        let (w, h) = (self.beauty.width, self.beauty.height);
        Image::from_fn(w, h, 3, |x, y, c| {
            self.catcher_with.get(x, y, c) - self.catcher_without.get(x, y, c)
        })
    }

    /// The composite over `plate` in `mode` ([`composite`]), or without a plate the CG render:
    /// objects and catchers with their shadows.
    pub fn composite_or_render(
        &self,
        plate: Option<&Image>,
        mode: CompositeMode,
    ) -> Result<Image, String> {
        match plate {
            Some(plate) => composite(self, plate, mode),
            None => {
                let (b, w) = (&self.beauty, &self.catcher_with);
                Ok(Image::from_fn(b.width, b.height, 3, |x, y, c| {
                    b.get(x, y, c) + w.get(x, y, c)
                }))
            }
        }
    }

    /// The layers a compositor reads, by name, after `composite`: beauty, shadow (the matte),
    /// shadow_difference, catcher_with, catcher_without, variance, samples.
    pub fn named(&self, composite: &Image) -> Vec<(String, Image)> {
        let named = [
            ("composite", composite.clone()),
            ("beauty", self.beauty.clone()),
            ("shadow", self.shadow_ratio()),
            ("shadow_difference", self.shadow_difference()),
            ("catcher_with", self.catcher_with.clone()),
            ("catcher_without", self.catcher_without.clone()),
            ("variance", self.variance.clone()),
            ("samples", self.samples.clone()),
        ];
        named.into_iter().map(|(n, i)| (n.to_string(), i)).collect()
    }

    /// The layers a composite needs (beauty, catcher_with, catcher_without) from [`Self::named`]
    /// layers (variance and samples zero): an error names a missing one and lists what there is.
    pub fn from_named(layers: &[(String, Image)]) -> Result<DifferentialLayers, String> {
        let get = |name: &str| {
            layers
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, i)| i.clone())
                .ok_or_else(|| {
                    format!(
                        "the layers have no `{name}` (they have: {}): connect \
                         differential_render's `layers`",
                        layers
                            .iter()
                            .map(|(n, _)| n.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })
        };
        let beauty = get("beauty")?;
        Ok(DifferentialLayers {
            catcher_with: get("catcher_with")?,
            catcher_without: get("catcher_without")?,
            variance: Image::new(beauty.width, beauty.height, 3),
            samples: Image::new(beauty.width, beauty.height, 1),
            beauty,
        })
    }
}

fn ratio(with: f32, without: f32) -> f32 {
    if without > 1e-12 {
        with / without
    } else {
        1.0
    }
}

/// Counters of a differential render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DifferentialStats {
    /// Pixels traced (the rest are plate).
    pub traced_pixels: u64,
    /// Pixels of the frame.
    pub pixels: u64,
    /// Samples taken over all traced pixels.
    pub samples: u64,
    /// Camera paths traced in the scene with objects.
    pub paths_with: u64,
    /// Camera paths traced in the local scene without objects.
    pub paths_without: u64,
    /// Samples dropped because their radiance was NaN or infinite.
    pub nonfinite: u64,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// The result: layers and counters.
#[derive(Clone, Debug)]
pub struct DifferentialOutput {
    /// The layers.
    pub layers: DifferentialLayers,
    /// Counters.
    pub stats: DifferentialStats,
}

/// Adaptive sampling: after `min_spp` samples, a pixel with `n` samples keeps sampling (in
/// batches of `min_spp`, up to the settings' `spp`) while the variance of the mean of what it
/// adds to the plate (B + W − Wo, largest channel) is above `(noise × m)² × n / min_spp`, `m`
/// the frame's mean rendered radiance: at `min_spp` samples the standard error must be below
/// `noise × m`, and each further batch must buy a fixed reduction of squared error per sample.
///
/// That is the allocation that minimizes the frame's total squared error for a number of
/// samples: a pixel of per-sample deviation σ has error σ²/n, one more sample removes about
/// σ²/n², and sampling while that gain exceeds a fixed price gives n ∝ σ — where a
/// fixed-error target (n ∝ σ²) pours the budget into the few noisiest pixels (caustics seen in
/// the catcher, the mirror's brightest reflections) until they hit the cap. On the book's shot
/// it reaches the book's noise with about half the samples (`vfxgraph bench shot`). Pixels
/// whose paths never meet the objects have zero variance and stop at `min_spp`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// Samples every traced pixel gets (and the batch size after that).
    pub min_spp: u32,
    /// Standard error a pixel must reach after `min_spp` samples, relative to the frame's mean
    /// rendered radiance (the price of a sample, see above).
    pub noise: f64,
}

/// The R2 low-discrepancy sequence's increments (Roberts 2018: the plastic number's powers),
/// used with a per-pixel random offset (Cranley–Patterson rotation) for the sub-pixel
/// positions: well spread for any sample count, so edges and reflections converge faster
/// than with independent jitter, and unbiased.
const R2: [f64; 2] = [0.754_877_666_246_692_7, 0.569_840_290_998_053_2];

/// One pixel's running sums.
struct Acc {
    s: PixelSampler,
    offset: [f64; 2],
    k: u32,
    beauty: Rgb,
    with: Rgb,
    without: Rgb,
    sum: Rgb,
    sq: Rgb,
    n_obj: u32,
    n_catch: u32,
    paths: [u64; 2],
    bad: u64,
}

impl Acc {
    fn new(seed: u64, index: u64) -> Acc {
        let mut s = PixelSampler::new(seed, index);
        let offset = [s.next(), s.next()];
        Acc {
            s,
            offset,
            k: 0,
            beauty: Rgb::BLACK,
            with: Rgb::BLACK,
            without: Rgb::BLACK,
            sum: Rgb::BLACK,
            sq: Rgb::BLACK,
            n_obj: 0,
            n_catch: 0,
            paths: [0; 2],
            bad: 0,
        }
    }

    /// Variance of the mean of B + (W − Wo), largest channel.
    fn variance_of_mean(&self) -> Rgb {
        if self.k < 2 {
            return Rgb::BLACK;
        }
        let n = self.k as f64;
        let mean = self.sum / n;
        let v = (self.sq / n - mean * mean) * (1.0 / (n - 1.0));
        Rgb::new(v.r.max(0.0), v.g.max(0.0), v.b.max(0.0))
    }
}

/// The two path tracers and what a sample needs.
struct Tracers<'a> {
    with_world: &'a World,
    with: PathTracer<'a>,
    without_world: &'a World,
    is_catcher: &'a [bool],
    gen: crate::camera::RayGenerator,
}

impl Tracers<'_> {
    /// Takes `count` more samples of pixel (x, y).
    fn sample(&self, acc: &mut Acc, x: usize, y: usize, count: u32) {
        for _ in 0..count {
            let i = acc.k as f64;
            acc.k += 1;
            let jx = (acc.offset[0] + i * R2[0]).fract();
            let jy = (acc.offset[1] + i * R2[1]).fract();
            let ray = self.gen.ray(x as f64 + jx - 0.5, y as f64 + jy - 0.5);
            let Some(hit) = self.with_world.intersect(&ray, f64::INFINITY) else {
                continue;
            };
            let catcher = match hit.surface {
                Surface::Material(m) => self.is_catcher[m as usize],
                Surface::Emitter(_) => false,
            };
            // The change this sample adds to the plate.
            let delta = if catcher {
                // The same random numbers for both (correlated sampling), one path until it
                // meets an object.
                let is_synthetic = |m: u32| !self.is_catcher[m as usize];
                let (lw, lo) = self.with.radiance_with_and_without(
                    self.without_world,
                    &is_synthetic,
                    ray,
                    &mut acc.s,
                );
                acc.paths[0] += 1;
                acc.paths[1] += 1;
                if !(lw.is_finite() && lo.is_finite()) {
                    acc.bad += 1;
                    continue;
                }
                acc.with += lw;
                acc.without += lo;
                acc.n_catch += 1;
                lw - lo
            } else {
                let l = self.with.radiance(ray, &mut acc.s);
                acc.paths[0] += 1;
                if !l.is_finite() {
                    acc.bad += 1;
                    continue;
                }
                acc.beauty += l;
                acc.n_obj += 1;
                l
            };
            acc.sum += delta;
            acc.sq += delta * delta;
        }
    }
}

/// Renders the layers of differential rendering for `scene` (objects + shadow catchers) seen
/// by `camera` under `environment` (book §10.10): `settings.spp` samples per traced pixel, or
/// with `adaptive`, between its `min_spp` and `settings.spp`. Per-pixel random streams as in
/// [`crate::render()`]: the result does not depend on the thread count.
pub fn differential_render(
    scene: &Scene,
    environment: &dyn Environment,
    camera: &Camera,
    settings: &RenderSettings,
    adaptive: Option<Adaptive>,
    progress: &(dyn Fn(f32) + Sync),
    cancel: Option<&AtomicBool>,
) -> Result<DifferentialOutput, RenderError> {
    camera.validate()?;
    if settings.spp == 0 {
        return Err(RenderError::BadSettings("spp must be positive".into()));
    }
    if let Some(a) = adaptive {
        if a.min_spp == 0 || !(a.noise.is_finite() && a.noise >= 0.0) {
            return Err(RenderError::BadSettings(format!(
                "adaptive sampling needs min_spp > 0 and a finite noise ≥ 0 (got {} and {})",
                a.min_spp, a.noise
            )));
        }
    }
    let start = Instant::now();
    let with_world = World::new(scene);
    let without_world = World::new(&scene.without_synthetic_objects());
    // `Surface::Material(m)`: m is the object's index in `scene.objects`.
    let is_catcher: Vec<bool> = scene.objects.iter().map(|o| o.catcher).collect();
    let tracer = |world| PathTracer {
        world,
        environment,
        max_depth: settings.max_depth,
        rr_depth: settings.rr_depth,
        strategy: settings.strategy,
    };
    let tracers = Tracers {
        with_world: &with_world,
        with: tracer(&with_world),
        without_world: &without_world,
        is_catcher: &is_catcher,
        gen: camera.rays(),
    };
    let (w, h) = (camera.width, camera.height);
    let traced = trace_mask(&with_world, camera, cancel)?;
    let cancelled = || cancel.is_some_and(|c| c.load(Ordering::Relaxed));
    let spp = settings.spp;
    let first = adaptive.map_or(spp, |a| a.min_spp.min(spp));
    // The traced pixels, in scanline order; `accs[i]` is pixel `pixels[i]`'s running sums.
    let pixels: Vec<usize> = (0..w * h).filter(|&p| traced[p]).collect();
    let done = AtomicUsize::new(0);
    let passes = if adaptive.is_some() { 2 } else { 1 };
    let step = (pixels.len() / 200).max(1);
    let tick = || {
        let d = done.fetch_add(1, Ordering::Relaxed) + 1;
        if d.is_multiple_of(step) {
            progress(d as f32 / (passes * pixels.len()).max(1) as f32);
        }
    };

    // Pass 1: every traced pixel gets `first` samples.
    let mut accs: Vec<Acc> = pixels
        .par_iter()
        .map(|&p| {
            let mut acc = Acc::new(settings.seed, p as u64);
            if !cancelled() {
                tracers.sample(&mut acc, p % w, p / w, first);
            }
            tick();
            acc
        })
        .collect();
    if cancelled() {
        return Err(RenderError::Cancelled);
    }

    // Pass 2: more samples where the pixel is noisier than the target.
    if let Some(a) = adaptive {
        let total: f64 = accs
            .iter()
            .map(|acc| ((acc.beauty + acc.with) / acc.k as f64).average())
            .sum();
        let mean = if accs.is_empty() {
            0.0
        } else {
            total / accs.len() as f64
        };
        let target = (a.noise * mean).powi(2);
        // Rounds: a pixel with k samples takes another batch while the largest variance of the
        // mean in its 3×3 neighbourhood is above target × k / min_spp (shadows and reflections
        // are spatially coherent: a pixel whose few samples all missed a rare event is kept
        // going by its neighbours). Only pixels next to one that sampled in the last round can
        // change their decision, so each round looks at those candidates only and costs what
        // they cost (the decisions, and so the image, are those of checking every pixel every
        // round).
        let mut var = vec![0.0f64; w * h];
        for (acc, &p) in accs.iter().zip(&pixels) {
            var[p] = acc.variance_of_mean().max_component();
        }
        let mut slot = vec![u32::MAX; w * h];
        for (i, &p) in pixels.iter().enumerate() {
            slot[p] = i as u32;
        }
        let neighbours = |p: usize| {
            let (x, y) = (p % w, p / w);
            (y.saturating_sub(1)..(y + 2).min(h)).flat_map(move |yy| {
                (x.saturating_sub(1)..(x + 2).min(w)).map(move |xx| yy * w + xx)
            })
        };
        let mut candidates: Vec<u32> = (0..pixels.len() as u32).collect();
        let mut active = vec![false; pixels.len()];
        let mut marked = vec![false; pixels.len()];
        loop {
            let sample_now: Vec<u32> = candidates
                .par_iter()
                .copied()
                .filter(|&i| {
                    let k = accs[i as usize].k;
                    let t = target * k as f64 / a.min_spp as f64;
                    k < spp && neighbours(pixels[i as usize]).any(|q| var[q] > t)
                })
                .collect();
            if cancelled() || sample_now.is_empty() {
                break;
            }
            for &i in &sample_now {
                active[i as usize] = true;
            }
            accs.par_iter_mut()
                .zip(active.par_iter())
                .enumerate()
                .filter(|(_, (_, &on))| on)
                .for_each(|(i, (acc, _))| {
                    let p = pixels[i];
                    tracers.sample(acc, p % w, p / w, a.min_spp.min(spp - acc.k));
                });
            // The next candidates: the traced neighbours of every pixel that just sampled.
            candidates.clear();
            for &i in &sample_now {
                active[i as usize] = false;
                let p = pixels[i as usize];
                var[p] = accs[i as usize].variance_of_mean().max_component();
                for q in neighbours(p) {
                    let j = slot[q];
                    if j != u32::MAX && !marked[j as usize] {
                        marked[j as usize] = true;
                        candidates.push(j);
                    }
                }
            }
            for &j in &candidates {
                marked[j as usize] = false;
            }
            candidates.sort_unstable();
        }
        if cancelled() {
            return Err(RenderError::Cancelled);
        }
        progress(1.0);
    }

    let mut beauty = Image::new(w, h, 4);
    let mut catcher_with = Image::new(w, h, 4);
    let mut catcher_without = Image::new(w, h, 4);
    let mut variance = Image::new(w, h, 3);
    let mut samples = Image::new(w, h, 1);
    let mut stats = DifferentialStats {
        pixels: (w * h) as u64,
        ..Default::default()
    };
    for (acc, &p) in accs.iter().zip(&pixels) {
        let (x, y) = (p % w, p / w);
        let n = acc.k as f64;
        let (b, wi, wo) = (acc.beauty / n, acc.with / n, acc.without / n);
        let (a_o, a_c) = (
            (acc.n_obj as f64 / n) as f32,
            (acc.n_catch as f64 / n) as f32,
        );
        let v = acc.variance_of_mean();
        beauty
            .pixel_mut(x, y)
            .copy_from_slice(&[b.r as f32, b.g as f32, b.b as f32, a_o]);
        catcher_with
            .pixel_mut(x, y)
            .copy_from_slice(&[wi.r as f32, wi.g as f32, wi.b as f32, a_c]);
        catcher_without.pixel_mut(x, y).copy_from_slice(&[
            wo.r as f32,
            wo.g as f32,
            wo.b as f32,
            a_c,
        ]);
        variance
            .pixel_mut(x, y)
            .copy_from_slice(&[v.r as f32, v.g as f32, v.b as f32]);
        samples.set(x, y, 0, acc.k as f32);
        stats.traced_pixels += 1;
        stats.samples += acc.k as u64;
        stats.paths_with += acc.paths[0];
        stats.paths_without += acc.paths[1];
        stats.nonfinite += acc.bad;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    Ok(DifferentialOutput {
        layers: DifferentialLayers {
            beauty,
            catcher_with,
            catcher_without,
            variance,
            samples,
        },
        stats,
    })
}

/// Which pixels to trace: rays through every pixel corner and centre; a pixel is traced when
/// any of its rays, or any of its 8 neighbours' rays, meets geometry (so an object thinner than
/// a pixel between two rays is still traced unless it is thinner than two pixels' gap).
fn trace_mask(
    world: &World,
    camera: &Camera,
    cancel: Option<&AtomicBool>,
) -> Result<Vec<bool>, RenderError> {
    let (w, h) = (camera.width, camera.height);
    let gen = camera.rays();
    let hits = |x: f64, y: f64| world.intersect(&gen.ray(x, y), f64::INFINITY).is_some();
    // Corner (i, j) is the point (i − 0.5, j − 0.5), i in 0..=w, j in 0..=h.
    let corners: Vec<Vec<bool>> = (0..=h)
        .into_par_iter()
        .map(|j| {
            (0..=w)
                .map(|i| hits(i as f64 - 0.5, j as f64 - 0.5))
                .collect()
        })
        .collect();
    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
        return Err(RenderError::Cancelled);
    }
    let own: Vec<bool> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let corners = &corners;
            let hits = &hits;
            (0..w).map(move |x| {
                corners[y][x]
                    || corners[y][x + 1]
                    || corners[y + 1][x]
                    || corners[y + 1][x + 1]
                    || hits(x as f64, y as f64)
            })
        })
        .collect();
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if own[y * w + x] {
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        mask[yy * w + xx] = true;
                    }
                }
            }
        }
    }
    Ok(mask)
}

/// The composite of `layers` over `plate` (RGB or RGBA; alpha ignored) in `mode` (see the
/// module documentation). The plate must have the layers' size.
pub fn composite(
    layers: &DifferentialLayers,
    plate: &Image,
    mode: CompositeMode,
) -> Result<Image, String> {
    let (w, h) = (layers.beauty.width, layers.beauty.height);
    if plate.width != w || plate.height != h {
        return Err(format!(
            "the plate is {}×{} but the render is {w}×{h}",
            plate.width, plate.height
        ));
    }
    if plate.color_channels() != 3 && plate.color_channels() != 1 {
        return Err(format!(
            "the plate has {} colour channels; expected RGB or gray",
            plate.color_channels()
        ));
    }
    let gray = plate.color_channels() == 1;
    let mut out = Image::new(w, h, 3);
    out.data
        .par_chunks_mut(w * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let b = layers.beauty.pixel(x, y);
                let wi = layers.catcher_with.pixel(x, y);
                let wo = layers.catcher_without.pixel(x, y);
                let (a_o, a_c) = (b[3], wi[3]);
                for c in 0..3 {
                    let p = plate.get(x, y, if gray { 0 } else { c });
                    row[x * 3 + c] = match mode {
                        CompositeMode::Additive => b[c] + (1.0 - a_o) * p + (wi[c] - wo[c]),
                        CompositeMode::Ratio => {
                            b[c] + (1.0 - a_o) * p + a_c * p * (ratio(wi[c], wo[c]) - 1.0)
                        }
                    };
                }
            }
        });
    Ok(out)
}

mod report;
#[cfg(test)]
mod tests;
