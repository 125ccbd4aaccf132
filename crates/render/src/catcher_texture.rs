//! The textured shadow catcher: the real ground's diffuse albedo per texel, estimated from the
//! plate (Debevec 1998, §4 "the local scene": the reflectance of the local scene is solved from
//! the photograph given the light; the book's §10.10.1 catcher is its one-colour special case,
//! [`crate::catcher_fit`]).
//!
//! A Lambertian surface under irradiance E reflects radiance L = ρ E / π, the same towards every
//! camera. So with E rendered at the catcher from the dome and the local scene (the catchers,
//! without the synthetic objects) and L read from a plate frame where a pixel's ray meets the
//! catcher, ρ = π L / E. Per frame, the plate pixels falling in a texel are averaged; over the
//! frames the per-texel estimates are combined by their median (robust to a frame where a texel
//! is occluded, grazing or misregistered). Texels no frame sees keep the fitted uniform colour.
//! The albedo is clamped to `[0, max_albedo]` (a physical range) and the clamped fraction
//! reported. E is smooth away from contact shadows, so it is estimated on a coarser grid than
//! the texels (`irradiance_cell` texels apart, `irradiance_samples` cosine-distributed paths per
//! point) and interpolated bilinearly over the grid points some camera centre sees (a point
//! under a proxy box standing on the catcher has E ≈ 0 and would inflate the albedo of the
//! seen texels next to the box). E is gathered on the side of the catcher the plate's rays
//! meet it from (a proxy box's face is seen from outside only). When catchers see one another
//! (proxy boxes next to the ground) E depends on their albedos, so the estimate repeats with the textured catcher in the
//! local scene (`iterations`), as [`crate::catcher_fit`] repeats its colour fit.
//!
//! The plate frames must be clean: if they already contain the objects (a shot filmed with the
//! real props, or the objects' own shadows), give only the frames before they enter (the node's
//! `frames` param).
//!
//! The result is a [`Texture::Planar`] on the catcher: a factor on its (fitted) colour, 1 where
//! unseen, looked up bilinearly by the path tracer.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;
use vfxgraph_imaging::Image;

use crate::brdf::Brdf;
use crate::camera::Camera;
use crate::environment::Environment;
use crate::integrator::{PathTracer, Sampler, Strategy};
use crate::math::{Frame, Rgb, Vec3};
use crate::ray::Ray;
use crate::render::PixelSampler;
use crate::sampling::{cosine_hemisphere, power_heuristic};
use crate::scene::{Scene, Shape};
use crate::texture::{PlanarMap, Texture};
use crate::world::{Surface, World};

/// Why an estimate failed.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// No such catcher.
    #[error("the scene has no shadow catcher number {0} (it has {1})")]
    NoCatcher(usize, usize),
    /// The catcher is not a planar polygon.
    #[error("shadow catcher {0} is not planar (a sphere, or triangles off one plane): only a planar catcher can be textured")]
    NotPlanar(usize),
    /// The catcher's material has no diffuse colour.
    #[error("shadow catcher {0} has a mirror material or a black colour: only a diffuse colour can be textured")]
    NotDiffuse(usize),
    /// No frames.
    #[error("no plate frames to estimate the texture from")]
    NoFrames,
    /// Plate and camera sizes differ.
    #[error("frame {frame}: the plate is {pw}×{ph} but the camera renders {cw}×{ch}")]
    PlateSize {
        /// Frame.
        frame: i64,
        /// Plate width.
        pw: usize,
        /// Plate height.
        ph: usize,
        /// Camera width.
        cw: usize,
        /// Camera height.
        ch: usize,
    },
    /// No frame sees the catcher.
    #[error("no texel of shadow catcher {catcher} is seen by any of the {frames} frames (frames {first}–{last}): is the catcher placed where the cameras look?")]
    NotSeen {
        /// Catcher index.
        catcher: usize,
        /// Frames used.
        frames: usize,
        /// First frame.
        first: i64,
        /// Last frame.
        last: i64,
    },
    /// Bad settings.
    #[error("{0}")]
    Settings(String),
    /// Cancelled.
    #[error("cancelled")]
    Cancelled,
}

/// One plate frame: its camera and its linear plate.
#[derive(Clone, Copy)]
pub struct View<'a> {
    /// Frame number.
    pub frame: i64,
    /// The camera (the solved one).
    pub camera: &'a Camera,
    /// The plate, linear radiance (RGB or gray).
    pub plate: &'a Image,
}

impl<'a> View<'a> {
    /// Frame `frame`'s view: its camera and plate.
    pub fn new(frame: i64, camera: &'a Camera, plate: &'a Image) -> Self {
        View {
            frame,
            camera,
            plate,
        }
    }
}

/// Settings of [`catcher_texture`] (the `catcher_texture` node's params, through
/// [`crate::local_scene::LocalTextureOptions`]).
#[derive(Clone, Copy, Debug, PartialEq, vfxgraph_params::Options)]
pub struct TextureOptions {
    /// which shadow catcher (0 = the scene's first), a planar one
    pub catcher: usize,
    /// texels along the catcher's longer side
    #[param(range = 1..=8192)]
    pub resolution: usize,
    /// spacing of the irradiance grid, in texels (irradiance is smooth away from contact
    /// shadows)
    #[param(range = 1..=256)]
    pub irradiance_cell: usize,
    /// paths per irradiance grid point
    #[param(range = 1..=1048576)]
    pub irradiance_samples: u32,
    /// maximum scattering vertices of the irradiance paths
    ///
    /// (Scattering vertices after the catcher.)
    #[param(range = 1..=64)]
    pub max_depth: u32,
    /// Seed of the irradiance paths.
    #[param(skip)]
    pub seed: u64,
    /// a texel is estimated when seen in at least this many frames (else it keeps the uniform
    /// colour)
    #[param(range = 1..=100000)]
    pub min_frames: usize,
    /// the physical albedo range's upper end (estimates are clamped to [0, max_albedo])
    #[param(range = 0.01..=1.0)]
    pub max_albedo: f64,
    /// estimates, each rendering the irradiance with the previous texture (catchers that see
    /// one another)
    #[param(range = 1..=10)]
    pub iterations: usize,
}

impl Default for TextureOptions {
    fn default() -> Self {
        TextureOptions {
            catcher: 0,
            resolution: 256,
            irradiance_cell: 4,
            irradiance_samples: 256,
            max_depth: 4,
            seed: 0,
            min_frames: 1,
            max_albedo: 0.95,
            iterations: 1,
        }
    }
}

/// What the estimate did.
#[derive(Clone, Debug)]
pub struct TextureReport {
    /// The estimated albedo, linear RGB, row j = texels along `map.v` (unseen texels hold the
    /// uniform colour).
    pub albedo: Image,
    /// Frames that saw each texel (row-major like `albedo`).
    pub seen: Vec<u16>,
    /// The map's rectangle (its texels are the factors put on the catcher).
    pub map: PlanarMap,
    /// The catcher's uniform colour the factors are relative to.
    pub uniform: [f64; 3],
    /// Texels estimated (seen in ≥ `min_frames` frames), and their fraction.
    pub estimated: usize,
    /// Fraction of estimated texel channels clamped to the physical range.
    pub clamped_fraction: f64,
    /// Plate pixels used per frame.
    pub pixels_per_frame: Vec<(i64, usize)>,
    /// Mean irradiance over the grid (per channel), for the report.
    pub mean_irradiance: [f64; 3],
}

fn diffuse(b: &Brdf) -> Option<Rgb> {
    match b {
        Brdf::Lambert(l) => Some(l.albedo),
        Brdf::BlinnPhong(p) => Some(p.diffuse),
        Brdf::Mirror(_) => None,
    }
}

/// One image row's pixels that meet the catcher first: (texel, plate radiance) each, and how
/// many of their rays meet it from the normal's side and from the other.
type RowHits = (Vec<(usize, [f64; 3])>, [usize; 2]);

/// The catcher's plane rectangle: origin, u, v edges and the unit normal facing `eye`. (The
/// estimate then turns the normal to the side the plate's rays meet the catcher from: a face
/// of a proxy box is seen only from outside, which need not be the first frame's side.)
fn rectangle(shape: &Shape, eye: Vec3) -> Option<(Vec3, Vec3, Vec3, Vec3)> {
    let Shape::Triangles { triangles } = shape else {
        return None;
    };
    let t0 = triangles.first()?;
    let e1 = t0[1] - t0[0];
    let mut n = e1.cross(t0[2] - t0[0]);
    if n.length().is_nan() || n.length() <= 0.0 {
        return None;
    }
    n = n.normalized();
    let u = e1.normalized();
    let v = n.cross(u);
    let o = t0[0];
    let (mut smin, mut smax, mut tmin, mut tmax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut size: f64 = 0.0;
    for tri in triangles {
        for &p in tri {
            let d = p - o;
            smin = smin.min(d.dot(u));
            smax = smax.max(d.dot(u));
            tmin = tmin.min(d.dot(v));
            tmax = tmax.max(d.dot(v));
            size = size.max(d.length());
        }
    }
    for tri in triangles {
        for &p in tri {
            if (p - o).dot(n).abs() > 1e-6 * size.max(1e-12) {
                return None;
            }
        }
    }
    if (eye - o).dot(n) < 0.0 {
        n = -n;
    }
    let origin = o + u * smin + v * tmin;
    Some((origin, u * (smax - smin), v * (tmax - tmin), n))
}

/// Estimates the diffuse albedo texture of a planar shadow catcher of `scene` from plate
/// frames `views` under `environment` (module docs); returns the scene with the texture on the
/// catcher and the report.
pub fn catcher_texture(
    scene: &Scene,
    environment: &dyn Environment,
    views: &[View<'_>],
    options: &TextureOptions,
    cancel: Option<&AtomicBool>,
) -> Result<(Scene, TextureReport), TextureError> {
    let o = options;
    if views.is_empty() {
        return Err(TextureError::NoFrames);
    }
    if o.resolution == 0 || o.resolution > 8192 {
        return Err(TextureError::Settings(format!(
            "resolution must be in 1–8192 texels, found {}",
            o.resolution
        )));
    }
    if o.irradiance_cell == 0 || o.irradiance_samples == 0 || o.iterations == 0 {
        return Err(TextureError::Settings(
            "irradiance_cell, irradiance_samples and iterations must be positive".into(),
        ));
    }
    if !(o.max_albedo > 0.0 && o.max_albedo <= 1.0) {
        return Err(TextureError::Settings(format!(
            "max_albedo must be in (0, 1], found {}",
            o.max_albedo
        )));
    }
    let catchers: Vec<usize> = (0..scene.objects.len())
        .filter(|&i| scene.objects[i].catcher)
        .collect();
    let &index = catchers
        .get(o.catcher)
        .ok_or(TextureError::NoCatcher(o.catcher, catchers.len()))?;
    let obj = &scene.objects[index];
    let uniform = diffuse(&obj.material)
        .filter(|c| c.r > 0.0 && c.g > 0.0 && c.b > 0.0)
        .ok_or(TextureError::NotDiffuse(o.catcher))?;
    for v in views {
        if (v.plate.width, v.plate.height) != (v.camera.width, v.camera.height) {
            return Err(TextureError::PlateSize {
                frame: v.frame,
                pw: v.plate.width,
                ph: v.plate.height,
                cw: v.camera.width,
                ch: v.camera.height,
            });
        }
    }
    let (origin, u, v, mut n) = rectangle(&obj.shape, views[0].camera.center())
        .ok_or(TextureError::NotPlanar(o.catcher))?;
    let (lu, lv) = (u.length(), v.length());
    let texel = lu.max(lv) / o.resolution as f64;
    let (w, h) = (
        ((lu / texel).ceil() as usize).max(1),
        ((lv / texel).ceil() as usize).max(1),
    );
    // The map covers whole texels: stretch the edges to w, h texels of side `texel`.
    let (u, v) = (u * (w as f64 * texel / lu), v * (h as f64 * texel / lv));
    let mut map = PlanarMap {
        origin,
        u,
        v,
        width: w,
        height: h,
        texels: vec![1.0; 3 * w * h],
    };
    // The local scene; `index` becomes `local_index` there (catchers only).
    let mut local = scene.without_synthetic_objects();
    let local_index = catchers.iter().position(|&i| i == index).unwrap_or(0) as u32;

    // Per frame, per texel: the mean plate radiance of the pixels whose ray meets the catcher
    // first inside the texel. Independent of the irradiance, so computed once.
    let world0 = World::new(&local);
    let mut per_texel: Vec<Vec<[f32; 3]>> = vec![Vec::new(); w * h];
    let mut pixels_per_frame = Vec::new();
    let (mut front, mut back) = (0usize, 0usize);
    for view in views {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(TextureError::Cancelled);
        }
        let (cw, ch) = (view.camera.width, view.camera.height);
        let rays = view.camera.rays();
        let gray = view.plate.color_channels() == 1;
        // Per row: (texel, radiance) of each pixel that meets the catcher first, and how many
        // of those rays meet it from the side `n` points to (the rest from the other side).
        let rows: Vec<RowHits> = (0..ch)
            .into_par_iter()
            .map(|y| {
                let mut out = Vec::new();
                let mut sides = [0usize; 2];
                for x in 0..cw {
                    let ray = rays.ray(x as f64, y as f64);
                    let Some(hit) = world0.intersect(&ray, f64::INFINITY) else {
                        continue;
                    };
                    if hit.surface != Surface::Material(local_index) {
                        continue;
                    }
                    sides[usize::from(ray.d.dot(n) > 0.0)] += 1;
                    let (s, t) = map.coords(hit.p);
                    if !(0.0..1.0).contains(&s) || !(0.0..1.0).contains(&t) {
                        continue;
                    }
                    let (i, j) = ((s * w as f64) as usize, (t * h as f64) as usize);
                    let c = |k| view.plate.get(x, y, if gray { 0 } else { k }) as f64;
                    let l = [c(0), c(1), c(2)];
                    if l.iter().all(|x| x.is_finite()) {
                        out.push((j * w + i, l));
                    }
                }
                (out, sides)
            })
            .collect();
        let mut sum = vec![[0.0f64; 4]; w * h];
        let mut used = 0;
        for (_, s) in &rows {
            front += s[0];
            back += s[1];
        }
        for (k, l) in rows.into_iter().flat_map(|(r, _)| r) {
            let s = &mut sum[k];
            s[0] += l[0];
            s[1] += l[1];
            s[2] += l[2];
            s[3] += 1.0;
            used += 1;
        }
        for (k, s) in sum.iter().enumerate() {
            if s[3] > 0.0 {
                per_texel[k].push([
                    (s[0] / s[3]) as f32,
                    (s[1] / s[3]) as f32,
                    (s[2] / s[3]) as f32,
                ]);
            }
        }
        pixels_per_frame.push((view.frame, used));
    }
    // The irradiance is gathered on the side the plate sees (most of its rays: a box face is
    // seen from outside only, whatever side the first frame's camera is on).
    if back > front {
        n = -n;
    }
    let seen: Vec<u16> = per_texel.iter().map(|v| v.len() as u16).collect();
    if seen.iter().all(|&s| s == 0) {
        return Err(TextureError::NotSeen {
            catcher: o.catcher,
            frames: views.len(),
            first: views.iter().map(|v| v.frame).min().unwrap_or(0),
            last: views.iter().map(|v| v.frame).max().unwrap_or(0),
        });
    }

    let mut albedo = Image::new(w, h, 3);
    let mut estimated = 0;
    let mut clamped = 0;
    let mut mean_irradiance = [0.0; 3];
    // The irradiance grid's points (`irradiance_cell` texels apart, just off the plane).
    let cell = o.irradiance_cell as f64;
    let (gw, gh) = (
        (w as f64 / cell).ceil() as usize + 1,
        (h as f64 / cell).ceil() as usize + 1,
    );
    let eps = 1e-6 * (1.0 + origin.max_abs() + u.length() + v.length());
    let points: Vec<Vec3> = (0..gw * gh)
        .map(|g| {
            let (gi, gj) = (g % gw, g / gw);
            let s = (gi as f64 * cell / w as f64).min(1.0);
            let t = (gj as f64 * cell / h as f64).min(1.0);
            map.point(s, t) + n * eps
        })
        .collect();
    // A grid point some camera centre sees is in the open; one no camera sees may be under a
    // proxy box standing on the catcher (its irradiance ≈ 0), and interpolating it would
    // darken the irradiance of the seen texels next to the box (and brighten their albedo):
    // such points are left out of the interpolation. (Geometry only: the same every iteration.)
    let open: Vec<bool> = points
        .par_iter()
        .map(|&q| {
            views.iter().any(|view| {
                let to = view.camera.center() - q;
                let d = to.length();
                d > 0.0 && !world0.occluded(&Ray::new(q, to * (1.0 / d)), d * (1.0 - 1e-9))
            })
        })
        .collect();
    for _ in 0..o.iterations {
        let world = World::new(&local);
        let tracer = PathTracer {
            world: &world,
            environment,
            max_depth: o.max_depth.max(1),
            rr_depth: 3,
            strategy: Strategy::Mis,
        };
        let frame = Frame::from_normal(n);
        let grid: Vec<Rgb> = (0..gw * gh)
            .into_par_iter()
            .map(|g| {
                if !open[g] || cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return Rgb::BLACK;
                }
                let q = points[g];
                let mut sampler = PixelSampler::new(o.seed, g as u64);
                let mut acc = Rgb::BLACK;
                let finite = |l: Rgb| l.r.is_finite() && l.g.is_finite() && l.b.is_finite();
                for _ in 0..o.irradiance_samples {
                    // E = ∫ L cos θ dω: the dome by MIS of its own importance sampling and
                    // cosine sampling (power heuristic), the local scene by cosine sampling.
                    let u_env = sampler.next2();
                    if let Some(es) = environment.sample(u_env) {
                        let cos = es.wi.dot(n);
                        if cos > 0.0
                            && es.pdf_solid_angle > 0.0
                            && !world.occluded(&Ray::new(q, es.wi), f64::INFINITY)
                        {
                            let p_cos = cos / std::f64::consts::PI;
                            let wgt = power_heuristic(es.pdf_solid_angle, p_cos);
                            let c = es.radiance * (cos * wgt / es.pdf_solid_angle);
                            if finite(c) {
                                acc += c;
                            }
                        }
                    }
                    let (wl, _) = cosine_hemisphere(sampler.next2());
                    let d = frame.to_world(wl);
                    let ray = Ray::new(q, d);
                    // cos θ / p_cos = π.
                    let c = if world.intersect(&ray, f64::INFINITY).is_some() {
                        tracer.radiance(ray, &mut sampler) * std::f64::consts::PI
                    } else {
                        let (l, p_env) = environment.radiance_and_pdf(d);
                        let p_cos = d.dot(n).max(0.0) / std::f64::consts::PI;
                        l * (std::f64::consts::PI * power_heuristic(p_cos, p_env))
                    };
                    if finite(c) {
                        acc += c;
                    }
                }
                acc * (1.0 / o.irradiance_samples as f64)
            })
            .collect();
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(TextureError::Cancelled);
        }
        mean_irradiance = [0.0; 3];
        let n_open = open.iter().filter(|&&o| o).count().max(1) as f64;
        for (e, _) in grid.iter().zip(&open).filter(|(_, &o)| o) {
            mean_irradiance[0] += e.r / n_open;
            mean_irradiance[1] += e.g / n_open;
            mean_irradiance[2] += e.b / n_open;
        }
        // Bilinear over the open grid points of the texel's cell (weights renormalised);
        // `None` when none of them is open (the texel is then not estimated).
        let irradiance = |i: usize, j: usize| -> Option<Rgb> {
            let x = ((i as f64 + 0.5) / cell).min((gw - 1) as f64);
            let y = ((j as f64 + 0.5) / cell).min((gh - 1) as f64);
            let (x0, y0) = (x.floor() as usize, y.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(gw - 1), (y0 + 1).min(gh - 1));
            let (fx, fy) = (x - x0 as f64, y - y0 as f64);
            let mut acc = Rgb::BLACK;
            let mut wsum = 0.0;
            for (a, b, wt) in [
                (x0, y0, (1.0 - fx) * (1.0 - fy)),
                (x1, y0, fx * (1.0 - fy)),
                (x0, y1, (1.0 - fx) * fy),
                (x1, y1, fx * fy),
            ] {
                if open[b * gw + a] && wt > 0.0 {
                    acc += grid[b * gw + a] * wt;
                    wsum += wt;
                }
            }
            (wsum > 1e-9).then(|| acc * (1.0 / wsum))
        };
        estimated = 0;
        clamped = 0;
        for j in 0..h {
            for i in 0..w {
                let k = j * w + i;
                let ests = &per_texel[k];
                let mut a = [uniform.r, uniform.g, uniform.b];
                let e = if ests.len() >= o.min_frames.max(1) {
                    irradiance(i, j)
                } else {
                    None
                };
                if let Some(e) = e {
                    estimated += 1;
                    let e = [e.r, e.g, e.b];
                    for c in 0..3 {
                        let mut vals: Vec<f64> = ests.iter().map(|l| l[c] as f64).collect();
                        let l = median(&mut vals);
                        let rho = if e[c] > 0.0 {
                            std::f64::consts::PI * l / e[c]
                        } else {
                            f64::NAN
                        };
                        let r = if rho.is_finite() {
                            rho
                        } else {
                            [uniform.r, uniform.g, uniform.b][c]
                        };
                        if !(0.0..=o.max_albedo).contains(&r) {
                            clamped += 1;
                        }
                        a[c] = r.clamp(0.0, o.max_albedo);
                    }
                }
                for (c, v) in a.iter().enumerate() {
                    albedo.set(i, j, c, *v as f32);
                }
                map.texels[3 * k] = (a[0] / uniform.r) as f32;
                map.texels[3 * k + 1] = (a[1] / uniform.g) as f32;
                map.texels[3 * k + 2] = (a[2] / uniform.b) as f32;
            }
        }
        local.objects[local_index as usize].texture = Some(Texture::Planar(map.clone()));
    }
    let mut out = scene.clone();
    out.objects[index].texture = Some(Texture::Planar(map.clone()));
    Ok((
        out,
        TextureReport {
            albedo,
            seen,
            map,
            uniform: [uniform.r, uniform.g, uniform.b],
            estimated,
            clamped_fraction: clamped as f64 / (3 * estimated.max(1)) as f64,
            pixels_per_frame,
            mean_irradiance,
        },
    ))
}

/// The median of `v` (sorted in place; the mean of the middle two for an even count).
pub(crate) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Lambert;
    use crate::environment::ConstantEnvironment;
    use crate::render::{render, RenderSettings};
    use crate::scene::Object;

    fn ground(albedo: Rgb, texture: Option<Texture>) -> Scene {
        let p = |x: f64, y: f64| Vec3::new(x, y, 0.0);
        let mut floor = Object::new(
            Shape::Triangles {
                triangles: vec![
                    [p(-2.0, -2.0), p(2.0, -2.0), p(2.0, 2.0)],
                    [p(-2.0, -2.0), p(2.0, 2.0), p(-2.0, 2.0)],
                ],
            },
            Brdf::Lambert(Lambert { albedo }),
        );
        floor.catcher = true;
        floor.texture = texture;
        Scene {
            camera: None,
            objects: vec![floor],
            lights: vec![],
            background: Rgb::BLACK,
            dome: None,
        }
    }

    fn camera(from: Vec3) -> Camera {
        Camera::look_at(from, Vec3::ZERO, Vec3::new(0.0, 0.0, 1.0), 60.0, 64, 48).unwrap()
    }

    /// Under a constant sky L₀ an open plane receives E = π L₀ exactly, so the estimate is
    /// the plate's ρ: a `cells`-textured ground rendered by the path tracer from two views is
    /// recovered texel by texel against the texel's mean true albedo (median relative error
    /// ≤ 3 % where seen twice; the plates' 64 spp and pixels straddling texel edges are the rest).
    #[test]
    fn recovers_a_cells_texture_under_a_constant_sky() {
        let env = ConstantEnvironment {
            radiance: Rgb::new(1.0, 0.9, 0.8),
        };
        let cells = Texture::Cells {
            size: 0.5,
            contrast: 0.8,
            seed: 3,
            color: true,
        };
        let truth = ground(Rgb::splat(0.6), Some(cells.clone()));
        let cams = [
            camera(Vec3::new(0.3, -3.0, 2.5)),
            camera(Vec3::new(-0.5, -2.5, 3.0)),
        ];
        let plates: Vec<Image> = cams
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let st = RenderSettings {
                    spp: 64,
                    max_depth: 2,
                    seed: 10 + i as u64,
                    ..Default::default()
                };
                render(&World::new(&truth), &env, c, &st, &|_| {}, None)
                    .unwrap()
                    .image
            })
            .collect();
        let views: Vec<View> = cams
            .iter()
            .zip(&plates)
            .enumerate()
            .map(|(i, (camera, plate))| View {
                frame: i as i64,
                camera,
                plate,
            })
            .collect();
        let opts = TextureOptions {
            resolution: 32,
            irradiance_samples: 64,
            min_frames: 2,
            ..Default::default()
        };
        let start = ground(Rgb::splat(0.3), None);
        let (scene, rep) = catcher_texture(&start, &env, &views, &opts, None).unwrap();
        assert!(matches!(scene.objects[0].texture, Some(Texture::Planar(_))));
        let mut errs = Vec::new();
        for j in 0..rep.map.height {
            for i in 0..rep.map.width {
                if rep.seen[j * rep.map.width + i] < 2 {
                    continue;
                }
                // The texel's area mean of the true factor (4 × 4 points).
                let mut f = Rgb::BLACK;
                for k in 0..16 {
                    let s = (i as f64 + (k % 4) as f64 / 4.0 + 0.125) / rep.map.width as f64;
                    let t = (j as f64 + (k / 4) as f64 / 4.0 + 0.125) / rep.map.height as f64;
                    f += cells.factor(rep.map.point(s, t)) * (1.0 / 16.0);
                }
                for (c, tr) in [f.r, f.g, f.b].into_iter().enumerate() {
                    let a = rep.albedo.get(i, j, c) as f64;
                    errs.push((a - 0.6 * tr).abs() / (0.6 * tr));
                }
            }
        }
        assert!(errs.len() > 600, "{}", errs.len());
        let m = median(&mut errs);
        assert!(m < 0.03, "median relative error {m}");
        assert_eq!(rep.clamped_fraction, 0.0);
        // The factor on the uniform colour reproduces the albedo.
        let Some(Texture::Planar(map)) = &scene.objects[0].texture else {
            unreachable!()
        };
        let p = map.point(0.5, 0.5);
        let a = map.lookup(p).r * 0.3;
        assert!(a > 0.0 && a <= 0.95);
    }

    #[test]
    fn unseen_catchers_and_bad_settings_are_clear_errors() {
        let env = ConstantEnvironment {
            radiance: Rgb::WHITE,
        };
        let s = ground(Rgb::splat(0.3), None);
        // A camera looking away from the ground.
        let away = Camera::look_at(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::new(0.0, 1.0, 0.0),
            60.0,
            16,
            12,
        )
        .unwrap();
        let plate = Image::new(16, 12, 3);
        let views = [View {
            frame: 7,
            camera: &away,
            plate: &plate,
        }];
        let e = catcher_texture(&s, &env, &views, &TextureOptions::default(), None).unwrap_err();
        assert!(matches!(e, TextureError::NotSeen { .. }), "{e}");
        assert!(e.to_string().contains("frames 7–7"), "{e}");
        let e = catcher_texture(&s, &env, &[], &TextureOptions::default(), None).unwrap_err();
        assert!(matches!(e, TextureError::NoFrames));
        let small = Image::new(8, 8, 3);
        let views = [View {
            frame: 1,
            camera: &away,
            plate: &small,
        }];
        let e = catcher_texture(&s, &env, &views, &TextureOptions::default(), None).unwrap_err();
        assert!(e.to_string().contains("8×8"), "{e}");
        let o = TextureOptions {
            catcher: 1,
            ..Default::default()
        };
        let e = catcher_texture(&s, &env, &views, &o, None).unwrap_err();
        assert!(matches!(e, TextureError::NoCatcher(1, 1)), "{e}");
    }
}
