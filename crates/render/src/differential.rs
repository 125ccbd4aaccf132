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

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use vfxgraph_imaging::Image;

use crate::camera::Camera;
use crate::environment::Environment;
use crate::integrator::{PathTracer, Sampler};
use crate::math::Rgb;
use crate::render::{PixelSampler, RenderError, RenderSettings};
use crate::scene::Scene;
use crate::world::{Surface, World};

/// How the catcher's change is applied to the plate (book §10.10).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum CompositeMode {
    /// plate + (with − without): Debevec 1998, the book's program.
    #[default]
    Additive,
    /// plate × with / without: a multiplicative shadow matte (Cycles' shadow catcher); never
    /// darker than black, and it keeps the plate's texture inside shadows.
    Ratio,
}

impl CompositeMode {
    /// Parses `additive` or `ratio`.
    pub fn parse(s: &str) -> Option<CompositeMode> {
        match s {
            "additive" => Some(CompositeMode::Additive),
            "ratio" => Some(CompositeMode::Ratio),
            _ => None,
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

/// Renders the layers of differential rendering for `scene` (objects + shadow catchers) seen
/// by `camera` under `environment` (book §10.10). Per-pixel random streams as in
/// [`crate::render()`]: the result does not depend on the thread count.
pub fn differential_render(
    scene: &Scene,
    environment: &dyn Environment,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(f32) + Sync),
    cancel: Option<&AtomicBool>,
) -> Result<DifferentialOutput, RenderError> {
    camera.validate()?;
    if settings.spp == 0 {
        return Err(RenderError::BadSettings("spp must be positive".into()));
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
    let (t_with, t_without) = (tracer(&with_world), tracer(&without_world));
    let (w, h) = (camera.width, camera.height);
    let gen = camera.rays();
    let traced = trace_mask(&with_world, camera, cancel)?;

    let done = AtomicUsize::new(0);
    let nonfinite = AtomicU64::new(0);
    let paths = [AtomicU64::new(0), AtomicU64::new(0)];
    let spp = settings.spp;
    let n = spp as f64;
    // Per pixel: beauty rgb, a_o, with rgb, a_c, without rgb, variance rgb.
    type Px = [f32; 15];
    let rows: Vec<Option<Vec<Px>>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut row = vec![[0f32; 15]; w];
            let (mut p_with, mut p_without, mut bad) = (0u64, 0u64, 0u64);
            for (x, out) in row.iter_mut().enumerate() {
                if !traced[y * w + x] {
                    continue;
                }
                if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return None;
                }
                let mut s = PixelSampler::new(settings.seed, (y * w + x) as u64);
                let (mut beauty, mut with, mut without) = (Rgb::BLACK, Rgb::BLACK, Rgb::BLACK);
                let (mut sum, mut sq) = (Rgb::BLACK, Rgb::BLACK);
                let (mut n_obj, mut n_catch) = (0u32, 0u32);
                for _ in 0..spp {
                    let (jx, jy) = (s.next(), s.next());
                    let ray = gen.ray(x as f64 + jx - 0.5, y as f64 + jy - 0.5);
                    let Some(hit) = with_world.intersect(&ray, f64::INFINITY) else {
                        continue;
                    };
                    let catcher = match hit.surface {
                        Surface::Material(m) => is_catcher[m as usize],
                        Surface::Emitter(_) => false,
                    };
                    // The change this sample adds to the plate.
                    let delta = if catcher {
                        let mut s2 = s.clone();
                        let lw = t_with.radiance(ray, &mut s);
                        let lo = t_without.radiance(ray, &mut s2);
                        p_with += 1;
                        p_without += 1;
                        if !(lw.is_finite() && lo.is_finite()) {
                            bad += 1;
                            continue;
                        }
                        with += lw;
                        without += lo;
                        n_catch += 1;
                        lw - lo
                    } else {
                        let l = t_with.radiance(ray, &mut s);
                        p_with += 1;
                        if !l.is_finite() {
                            bad += 1;
                            continue;
                        }
                        beauty += l;
                        n_obj += 1;
                        l
                    };
                    sum += delta;
                    sq += delta * delta;
                }
                let mean = sum / n;
                let var = if spp > 1 {
                    let v = (sq / n - mean * mean) * (1.0 / (n - 1.0));
                    Rgb::new(v.r.max(0.0), v.g.max(0.0), v.b.max(0.0))
                } else {
                    Rgb::BLACK
                };
                let (b, wi, wo) = (beauty / n, with / n, without / n);
                *out = [
                    b.r as f32,
                    b.g as f32,
                    b.b as f32,
                    (n_obj as f64 / n) as f32,
                    wi.r as f32,
                    wi.g as f32,
                    wi.b as f32,
                    (n_catch as f64 / n) as f32,
                    wo.r as f32,
                    wo.g as f32,
                    wo.b as f32,
                    var.r as f32,
                    var.g as f32,
                    var.b as f32,
                    0.0,
                ];
            }
            paths[0].fetch_add(p_with, Ordering::Relaxed);
            paths[1].fetch_add(p_without, Ordering::Relaxed);
            nonfinite.fetch_add(bad, Ordering::Relaxed);
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(d as f32 / h as f32);
            Some(row)
        })
        .collect();
    let mut beauty = Image::new(w, h, 4);
    let mut catcher_with = Image::new(w, h, 4);
    let mut catcher_without = Image::new(w, h, 4);
    let mut variance = Image::new(w, h, 3);
    for (y, row) in rows.into_iter().enumerate() {
        let row = row.ok_or(RenderError::Cancelled)?;
        for (x, px) in row.iter().enumerate() {
            beauty.pixel_mut(x, y).copy_from_slice(&px[0..4]);
            catcher_with.pixel_mut(x, y).copy_from_slice(&px[4..8]);
            let wo = catcher_without.pixel_mut(x, y);
            wo[..3].copy_from_slice(&px[8..11]);
            wo[3] = px[7];
            variance.pixel_mut(x, y).copy_from_slice(&px[11..14]);
        }
    }
    let [pw, pwo] = paths;
    Ok(DifferentialOutput {
        layers: DifferentialLayers {
            beauty,
            catcher_with,
            catcher_without,
            variance,
        },
        stats: DifferentialStats {
            traced_pixels: traced.iter().filter(|&&t| t).count() as u64,
            pixels: (w * h) as u64,
            paths_with: pw.into_inner(),
            paths_without: pwo.into_inner(),
            nonfinite: nonfinite.into_inner(),
            seconds: start.elapsed().as_secs_f64(),
        },
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

#[cfg(test)]
mod tests;
