//! The shadow catcher's colour fit (book §10.10, the "polyshadow colour adjust" program): the
//! catcher stands for the real ground, so its diffuse colour is scaled until its render under
//! the dome matches the plate over the pixels it covers —
//! colour ← colour × mean(plate) / mean(render), per channel.
//!
//! Only the local scene is rendered (the catchers, lights and dome: the plate has no synthetic
//! objects), and only pixels the catchers cover entirely count (edge pixels mix in whatever is
//! beside the catcher in the plate). When the local scene has interreflections between catchers
//! the render is not exactly proportional to the colour, so the fit repeats until the
//! per-channel correction is below `tolerance`.

use std::sync::atomic::AtomicBool;

use vfxgraph_imaging::Image;

use crate::brdf::Brdf;
use crate::camera::{Camera, ImageSize};
use crate::differential::{differential_render, SHOT_MAX_DEPTH};
use crate::environment::Environment;
use crate::math::Rgb;
use crate::render::{mix_seed, RenderError, RenderSettings};
use crate::scene::Scene;

/// Why a fit failed.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The scene has no shadow catcher.
    #[error("the scene has no shadow catcher to fit")]
    NoCatcher,
    /// A catcher's material has no diffuse colour.
    #[error("shadow catcher {0} has a mirror material: only a diffuse colour can be fitted")]
    NotDiffuse(usize),
    /// The catchers cover no whole pixel of this frame.
    #[error(
        "the shadow catchers cover no whole pixel seen by this camera (is it the right frame?)"
    )]
    NotSeen,
    /// The plate does not match the camera.
    #[error("the plate is {pw}×{ph} but the camera renders {cw}×{ch} (set width/height)")]
    PlateSize {
        /// Plate width.
        pw: usize,
        /// Plate height.
        ph: usize,
        /// Camera width.
        cw: usize,
        /// Camera height.
        ch: usize,
    },
    /// The plate or the render is black or non-finite under the catcher.
    #[error("channel {channel}: mean plate {plate} and mean render {render} over the catcher cannot be matched")]
    Degenerate {
        /// Channel index.
        channel: usize,
        /// Mean plate value.
        plate: f64,
        /// Mean render value.
        render: f64,
    },
    /// The render failed.
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// What the fit did.
#[derive(Clone, Debug, PartialEq)]
pub struct CatcherFit {
    /// The total per-channel factor applied to the catchers' diffuse colours.
    pub ratio: [f64; 3],
    /// The first catcher's diffuse colour before and after.
    pub before: [f64; 3],
    /// After.
    pub after: [f64; 3],
    /// Pixels used (covered entirely by catchers).
    pub pixels: usize,
    /// Mean plate over those pixels, per channel.
    pub mean_plate: [f64; 3],
    /// Per-channel RMS of (plate − fitted render) / mean(plate) over those pixels: what a
    /// single colour cannot explain (texture of the real ground, noise, misregistration).
    pub residual: [f64; 3],
    /// Renders made.
    pub iterations: usize,
}

impl CatcherFit {
    /// What the `fit_catcher` node reports for a fit on plate frame `frame`.
    pub fn report(&self, frame: i64) -> serde_json::Value {
        serde_json::json!({
            "frame": frame,
            "ratio": self.ratio,
            "colour_before": self.before,
            "colour_after": self.after,
            "pixels": self.pixels,
            "mean_plate": self.mean_plate,
            "relative_residual_rms": self.residual,
            "renders": self.iterations,
        })
    }
}

fn diffuse(b: &Brdf) -> Option<Rgb> {
    match b {
        Brdf::Lambert(l) => Some(l.albedo),
        Brdf::BlinnPhong(p) => Some(p.diffuse),
        Brdf::Mirror(_) => None,
    }
}

fn scale_diffuse(b: &mut Brdf, k: [f64; 3]) {
    let s = |c: &mut Rgb| *c = Rgb::new(c.r * k[0], c.g * k[1], c.b * k[2]);
    match b {
        Brdf::Lambert(l) => s(&mut l.albedo),
        Brdf::BlinnPhong(p) => s(&mut p.diffuse),
        Brdf::Mirror(_) => {}
    }
}

/// Settings of [`fit_catcher`].
#[derive(Clone, Copy, Debug)]
pub struct FitOptions {
    /// The renders' settings.
    pub settings: RenderSettings,
    /// At most this many renders.
    pub max_iterations: usize,
    /// Stop when every channel's correction is within this (relative).
    pub tolerance: f64,
}

/// The `fit_catcher` node's options (besides its frame): the renders' sampling, the fit's
/// stopping rule and the image size.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct FitCatcherOptions {
    /// samples (paths) per pixel
    #[param(range = 1..=(1 << 20))]
    pub spp: u32,
    /// maximum scattering vertices per path (the book's shot used 2 bounces)
    #[param(range = 0..=1024)]
    pub max_depth: u32,
    /// extra seed mixed into the graph seed
    pub seed: u64,
    /// at most this many renders
    #[param(range = 1..=20)]
    pub iterations: usize,
    /// stop when every channel's correction is within this (relative)
    #[param(range = 0.0..=1.0)]
    pub tolerance: f64,
    #[param(flatten)]
    pub size: ImageSize,
}

impl Default for FitCatcherOptions {
    fn default() -> Self {
        FitCatcherOptions {
            spp: RenderSettings::default().spp,
            max_depth: SHOT_MAX_DEPTH,
            seed: 0,
            iterations: 4,
            tolerance: 1e-3,
            size: ImageSize::default(),
        }
    }
}

impl FitCatcherOptions {
    /// The fit's options, the renders seeded by `graph_seed` mixed with `seed`.
    pub fn fit(&self, graph_seed: u64) -> FitOptions {
        FitOptions {
            settings: RenderSettings {
                spp: self.spp,
                max_depth: self.max_depth,
                seed: mix_seed(graph_seed, self.seed),
                ..Default::default()
            },
            max_iterations: self.iterations,
            tolerance: self.tolerance,
        }
    }
}

/// Fits the catchers' diffuse colour of `scene` to `plate` (linear radiance, RGB) seen by
/// `camera` under `environment`; returns the scene with the fitted colour.
pub fn fit_catcher(
    scene: &Scene,
    environment: &dyn Environment,
    camera: &Camera,
    plate: &Image,
    options: &FitOptions,
    cancel: Option<&AtomicBool>,
) -> Result<(Scene, CatcherFit), FitError> {
    let (settings, max_iterations, tolerance) =
        (&options.settings, options.max_iterations, options.tolerance);
    let first = scene
        .objects
        .iter()
        .position(|o| o.catcher)
        .ok_or(FitError::NoCatcher)?;
    for (i, o) in scene.objects.iter().enumerate() {
        if o.catcher && diffuse(&o.material).is_none() {
            return Err(FitError::NotDiffuse(i));
        }
    }
    if plate.width != camera.width || plate.height != camera.height {
        return Err(FitError::PlateSize {
            pw: plate.width,
            ph: plate.height,
            cw: camera.width,
            ch: camera.height,
        });
    }
    let gray = plate.color_channels() == 1;
    let before = diffuse(&scene.objects[first].material).unwrap_or(Rgb::BLACK);
    let mut local = scene.without_synthetic_objects();
    let mut total = [1.0f64; 3];
    let mut iterations = 0;
    loop {
        iterations += 1;
        let out =
            differential_render(&local, environment, camera, settings, None, &|_| {}, cancel)?;
        let layer = &out.layers.catcher_with;
        let mut pixels = Vec::new();
        for y in 0..layer.height {
            for x in 0..layer.width {
                if layer.get(x, y, 3) == 1.0 {
                    pixels.push((x, y));
                }
            }
        }
        if pixels.is_empty() {
            return Err(FitError::NotSeen);
        }
        let plate_at = |x, y, c| plate.get(x, y, if gray { 0 } else { c }) as f64;
        let mut step = [1.0; 3];
        let mut mean_plate = [0.0; 3];
        for c in 0..3 {
            let n = pixels.len() as f64;
            let mp: f64 = pixels.iter().map(|&(x, y)| plate_at(x, y, c)).sum::<f64>() / n;
            let mr: f64 = pixels
                .iter()
                .map(|&(x, y)| layer.get(x, y, c) as f64)
                .sum::<f64>()
                / n;
            if !(mp.is_finite() && mr.is_finite() && mp > 0.0 && mr > 0.0) {
                return Err(FitError::Degenerate {
                    channel: c,
                    plate: mp,
                    render: mr,
                });
            }
            step[c] = mp / mr;
            mean_plate[c] = mp;
        }
        for (t, s) in total.iter_mut().zip(step) {
            *t *= s;
        }
        for o in local.objects.iter_mut().filter(|o| o.catcher) {
            scale_diffuse(&mut o.material, step);
        }
        let converged = step.iter().all(|s| (s - 1.0).abs() <= tolerance);
        if converged || iterations >= max_iterations {
            let mut residual = [0.0; 3];
            for c in 0..3 {
                let ss: f64 = pixels
                    .iter()
                    .map(|&(x, y)| {
                        let r = layer.get(x, y, c) as f64 * step[c];
                        (plate_at(x, y, c) - r).powi(2)
                    })
                    .sum();
                residual[c] = (ss / pixels.len() as f64).sqrt() / mean_plate[c];
            }
            let mut fitted = scene.clone();
            for o in fitted.objects.iter_mut().filter(|o| o.catcher) {
                scale_diffuse(&mut o.material, total);
            }
            let after = diffuse(&fitted.objects[first].material).unwrap_or(Rgb::BLACK);
            return Ok((
                fitted,
                CatcherFit {
                    ratio: total,
                    before: [before.r, before.g, before.b],
                    after: [after.r, after.g, after.b],
                    pixels: pixels.len(),
                    mean_plate,
                    residual,
                    iterations,
                },
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Lambert;
    use crate::environment::ConstantEnvironment;
    use crate::math::Vec3;
    use crate::render::render;
    use crate::scene::{Object, Shape};
    use crate::shape::Sphere;
    use crate::World;

    fn scene(albedo: Rgb) -> Scene {
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
        let ball = Object::new(
            Shape::Sphere(Sphere {
                center: Vec3::new(0.0, 0.0, 0.5),
                radius: 0.5,
            }),
            Brdf::Lambert(Lambert {
                albedo: Rgb::splat(0.9),
            }),
        );
        Scene {
            camera: Some(
                Camera::look_at(
                    Vec3::new(0.0, -4.0, 2.0),
                    Vec3::new(0.0, 0.0, 0.0),
                    Vec3::new(0.0, 0.0, 1.0),
                    50.0,
                    40,
                    30,
                )
                .unwrap(),
            ),
            objects: vec![floor, ball],
            lights: vec![],
            background: Rgb::new(1.0, 0.9, 0.7),
            dome: None,
        }
    }

    /// The plate is a render of the ground with a known colour; a catcher starting from grey
    /// must come out with that colour (the synthetic ball, absent from the plate, is ignored).
    #[test]
    fn recovers_the_colour_the_plate_was_made_with() {
        let truth = Rgb::new(0.62, 0.41, 0.23);
        let real = scene(truth).without_synthetic_objects();
        let env = ConstantEnvironment {
            radiance: real.background,
        };
        let settings = RenderSettings {
            spp: 64,
            max_depth: 3,
            seed: 1,
            ..Default::default()
        };
        let plate = render(
            &World::new(&real),
            &env,
            real.camera.as_ref().unwrap(),
            &settings,
            &|_| {},
            None,
        )
        .unwrap()
        .image;
        let start = scene(Rgb::splat(0.5));
        let options = FitOptions {
            settings: RenderSettings {
                seed: 2,
                ..settings
            },
            max_iterations: 4,
            tolerance: 1e-3,
        };
        let (fitted, fit) = fit_catcher(
            &start,
            &env,
            start.camera.as_ref().unwrap(),
            &plate,
            &options,
            None,
        )
        .unwrap();
        for (c, t) in [truth.r, truth.g, truth.b].into_iter().enumerate() {
            let rel = (fit.after[c] - t).abs() / t;
            assert!(rel < 0.01, "channel {c}: {} vs {t} ({fit:?})", fit.after[c]);
        }
        assert!(fit.pixels > 200, "{fit:?}");
        assert!(fit.residual.iter().all(|r| *r < 0.05), "{fit:?}");
        // The objects are kept; only the catcher changed.
        assert_eq!(fitted.objects.len(), 2);
        assert_eq!(fitted.objects[1], start.objects[1]);
    }

    #[test]
    fn errors_are_clear() {
        let s = scene(Rgb::splat(0.5));
        let env = ConstantEnvironment {
            radiance: Rgb::WHITE,
        };
        let st = FitOptions {
            settings: RenderSettings {
                spp: 2,
                ..Default::default()
            },
            max_iterations: 2,
            tolerance: 1e-3,
        };
        let plate = Image::new(40, 30, 3);
        let e = fit_catcher(
            &s,
            &env,
            s.camera.as_ref().unwrap(),
            &Image::new(8, 8, 3),
            &st,
            None,
        )
        .unwrap_err();
        assert!(e.to_string().contains("8×8"), "{e}");
        // A black plate cannot be matched.
        let e = fit_catcher(&s, &env, s.camera.as_ref().unwrap(), &plate, &st, None).unwrap_err();
        assert!(matches!(e, FitError::Degenerate { .. }), "{e}");
        let mut none = s.clone();
        none.objects.retain(|o| !o.catcher);
        let e =
            fit_catcher(&none, &env, s.camera.as_ref().unwrap(), &plate, &st, None).unwrap_err();
        assert!(matches!(e, FitError::NoCatcher));
    }
}
