//! The image loop: tiles on rayon, one PCG stream per pixel (so the image does not depend on
//! the thread count or the tile order), box-filtered jittered samples, per-pixel variance,
//! progress and cancellation (book §9.13, the rendering program).

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::Instant;

use rand_core::{RngCore, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;
use vfxgraph_imaging::Image;

use crate::camera::{Camera, ImageSize};
use crate::environment::Environment;
use crate::integrator::{PathTracer, Sampler, Strategy};
use crate::light::LightSampling;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::world::World;

/// Why a render stopped.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RenderError {
    /// The cancel flag was raised.
    #[error("render cancelled")]
    Cancelled,
    /// Settings out of range.
    #[error("bad render settings: {0}")]
    BadSettings(String),
    /// The camera is invalid.
    #[error(transparent)]
    Camera(#[from] crate::camera::CameraError),
    /// Samples of non-finite radiance were dropped: a bug in the tracer, not in the scene.
    #[error("{0} samples had non-finite radiance (a bug: please report the scene)")]
    NonFinite(u64),
}

impl RenderError {
    /// [`RenderError::NonFinite`] when a render dropped `nonfinite` samples.
    pub fn check_finite(nonfinite: u64) -> Result<(), RenderError> {
        match nonfinite {
            0 => Ok(()),
            n => Err(RenderError::NonFinite(n)),
        }
    }
}

/// Render settings.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Samples (paths) per pixel.
    pub spp: u32,
    /// Maximum scattering vertices per path (the book's bounces).
    pub max_depth: u32,
    /// Russian roulette starts at this depth.
    pub rr_depth: u32,
    /// Seed of the per-pixel random streams.
    pub seed: u64,
    /// Tile edge in pixels.
    pub tile: usize,
    /// Estimator combination.
    pub strategy: Strategy,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            spp: 64,
            max_depth: 8,
            rr_depth: 3,
            seed: 0,
            tile: 16,
            strategy: Strategy::Mis,
        }
    }
}

/// A node's extra `seed` mixed into the graph's seed (golden-ratio multiply, then xor): seed 0
/// keeps the graph's.
pub fn mix_seed(graph_seed: u64, seed: u64) -> u64 {
    graph_seed ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Which objects of the scene a render sees.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum Objects {
    /// Every object.
    #[default]
    All,
    /// Shadow catchers, lights and dome only (the empty-set render of differential rendering).
    CatchersOnly,
}

/// The `render` node's options: sampling, image size, objects and light sampling.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct RenderOptions {
    /// samples (paths) per pixel
    #[param(range = 1..=(1 << 20))]
    pub spp: u32,
    /// maximum scattering vertices per path (the book's bounces; its Cornell render used 3)
    #[param(range = 0..=1024)]
    pub max_depth: u32,
    /// extra seed mixed into the graph seed
    pub seed: u64,
    #[param(flatten)]
    pub size: ImageSize,
    /// `catchers_only` drops the synthetic objects, keeping shadow catchers, lights and dome (the empty-set render of differential rendering, book §10.10)
    pub objects: Objects,
    /// how next-event estimation picks a point on a light triangle: uniformly by area (book §9.11) or by the solid angle it subtends (Arvo 1995; less noise from large, near lights)
    pub light_sampling: LightSampling,
}

impl Default for RenderOptions {
    fn default() -> Self {
        let d = RenderSettings::default();
        RenderOptions {
            spp: d.spp,
            max_depth: d.max_depth,
            seed: 0,
            size: ImageSize::default(),
            objects: Objects::All,
            light_sampling: LightSampling::Area,
        }
    }
}

impl RenderOptions {
    /// The settings of a render seeded by `graph_seed` (mixed with `seed`), next-event
    /// estimation combined with BRDF sampling.
    pub fn settings(&self, graph_seed: u64) -> RenderSettings {
        RenderSettings {
            spp: self.spp,
            max_depth: self.max_depth,
            seed: mix_seed(graph_seed, self.seed),
            strategy: Strategy::Mis,
            ..Default::default()
        }
    }

    /// The world of `scene` as `objects` and `light_sampling` say.
    pub fn world(&self, scene: &Scene) -> World {
        match self.objects {
            Objects::All => World::with_light_sampling(scene, self.light_sampling),
            Objects::CatchersOnly => {
                World::with_light_sampling(&scene.without_synthetic_objects(), self.light_sampling)
            }
        }
    }
}

/// Counters of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Paths traced (pixels × spp).
    pub paths: u64,
    /// Samples dropped because their radiance was NaN or infinite.
    pub nonfinite: u64,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// A rendered image with its per-pixel variance.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Mean radiance per pixel, linear RGB, rows top-down.
    pub image: Image,
    /// Variance of each pixel's mean (sample variance / spp), per channel.
    pub variance: Image,
    /// Counters.
    pub stats: RenderStats,
}

/// The per-pixel random stream: PCG32 (O'Neill 2014) seeded from (seed, pixel); each pixel owns
/// its stream, so any schedule gives the same numbers.
#[derive(Clone)]
pub struct PixelSampler(Pcg32);

impl PixelSampler {
    /// The stream of pixel `index` for `seed`.
    pub fn new(seed: u64, index: u64) -> PixelSampler {
        let state = splitmix64(seed ^ splitmix64(index.wrapping_add(0x9E37_79B9_7F4A_7C15)));
        PixelSampler(Pcg32::new(state, index))
    }
}

impl Sampler for PixelSampler {
    #[inline]
    fn next(&mut self) -> f64 {
        self.0.next_u32() as f64 * (1.0 / 4_294_967_296.0)
    }
}

/// A seeded sampler for tests and tools.
pub fn seeded_sampler(seed: u64) -> PixelSampler {
    PixelSampler(Pcg32::seed_from_u64(seed))
}

fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Renders `world` seen by `camera` (book §9.13). `progress` receives the fraction of tiles
/// done; raising `cancel` stops the render with [`RenderError::Cancelled`].
pub fn render(
    world: &World,
    environment: &dyn Environment,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(f32) + Sync),
    cancel: Option<&AtomicBool>,
) -> Result<RenderOutput, RenderError> {
    camera.validate()?;
    if settings.spp == 0 || settings.tile == 0 {
        return Err(RenderError::BadSettings(
            "spp and tile must be positive".into(),
        ));
    }
    let (w, h) = (camera.width, camera.height);
    // The image's size is checked before a tile is traced (not once every tile is buffered).
    let limit = vfxgraph_imaging::image::MAX_SAMPLES;
    if w.checked_mul(h)
        .and_then(|n| n.checked_mul(3))
        .is_none_or(|n| n > limit)
    {
        return Err(RenderError::BadSettings(format!(
            "a {w}×{h} image is over the image limit ({limit} samples)"
        )));
    }
    let start = Instant::now();
    let gen = camera.rays();
    let tracer = PathTracer {
        world,
        environment,
        max_depth: settings.max_depth,
        rr_depth: settings.rr_depth,
        strategy: settings.strategy,
    };
    let ts = settings.tile;
    let tiles: Vec<(usize, usize)> = (0..h.div_ceil(ts))
        .flat_map(|ty| (0..w.div_ceil(ts)).map(move |tx| (tx * ts, ty * ts)))
        .collect();
    let done = AtomicUsize::new(0);
    let nonfinite = AtomicU64::new(0);
    let spp = settings.spp;
    let results: Vec<Option<Vec<[f32; 6]>>> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                return None;
            }
            let (x1, y1) = ((x0 + ts).min(w), (y0 + ts).min(h));
            let mut out = Vec::with_capacity((x1 - x0) * (y1 - y0));
            let mut bad = 0u64;
            for y in y0..y1 {
                for x in x0..x1 {
                    // Per pixel too: at high spp one tile can take seconds.
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return None;
                    }
                    let mut s = PixelSampler::new(settings.seed, (y * w + x) as u64);
                    let (mut sum, mut sq) = (Rgb::BLACK, Rgb::BLACK);
                    for _ in 0..spp {
                        let (jx, jy) = (s.next(), s.next());
                        let ray = gen.ray(x as f64 + jx - 0.5, y as f64 + jy - 0.5);
                        let l = tracer.radiance(ray, &mut s);
                        if l.is_finite() {
                            sum += l;
                            sq += l * l;
                        } else {
                            bad += 1;
                        }
                    }
                    let n = spp as f64;
                    let mean = sum / n;
                    let var = if spp > 1 {
                        let v = (sq / n - mean * mean) * (1.0 / (n - 1.0));
                        Rgb::new(v.r.max(0.0), v.g.max(0.0), v.b.max(0.0))
                    } else {
                        Rgb::BLACK
                    };
                    out.push([
                        mean.r as f32,
                        mean.g as f32,
                        mean.b as f32,
                        var.r as f32,
                        var.g as f32,
                        var.b as f32,
                    ]);
                }
            }
            nonfinite.fetch_add(bad, Ordering::Relaxed);
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(d as f32 / tiles.len() as f32);
            Some(out)
        })
        .collect();
    let mut image = Image::new(w, h, 3);
    let mut variance = Image::new(w, h, 3);
    for (&(x0, y0), tile) in tiles.iter().zip(results) {
        let tile = tile.ok_or(RenderError::Cancelled)?;
        let x1 = (x0 + ts).min(w);
        for (i, px) in tile.iter().enumerate() {
            let (x, y) = (x0 + i % (x1 - x0), y0 + i / (x1 - x0));
            image.pixel_mut(x, y).copy_from_slice(&px[..3]);
            variance.pixel_mut(x, y).copy_from_slice(&px[3..]);
        }
    }
    Ok(RenderOutput {
        image,
        variance,
        stats: RenderStats {
            paths: (w * h) as u64 * spp as u64,
            nonfinite: nonfinite.into_inner(),
            seconds: start.elapsed().as_secs_f64(),
        },
    })
}

/// Runs `f` with a `Sync` progress callback (what the renders take) forwarding to `progress`,
/// which need not be `Sync`: calls are serialized through a mutex.
pub fn with_sync_progress<R>(
    progress: impl Fn(f32) + Send,
    f: impl FnOnce(&(dyn Fn(f32) + Sync)) -> R,
) -> R {
    let progress = std::sync::Mutex::new(progress);
    f(&|x| {
        if let Ok(cb) = progress.lock() {
            cb(x)
        }
    })
}
