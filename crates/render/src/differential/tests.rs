//! Differential rendering against truth renders of the same scene: the "real world" is the
//! local scene (the catcher) itself, so the plate is a render of the catcher alone and the
//! truth is a render with the objects; the composite must equal the truth within the noise.

use super::*;
use crate::brdf::{Brdf, Lambert};
use crate::environment::ConstantEnvironment;
use crate::math::Vec3;
use crate::render::render;
use crate::scene::{AreaLight, Object, Shape};
use crate::shape::Sphere;

fn quad(z: f64, r: f64) -> Shape {
    let p = |x: f64, y: f64| Vec3::new(x, y, z);
    Shape::Triangles {
        triangles: vec![
            [p(-r, -r), p(r, -r), p(r, r)],
            [p(-r, -r), p(r, r), p(-r, r)],
        ],
    }
}

/// A grey catcher floor, a diffuse sphere resting on it, a square light above and a dim sky;
/// the camera sees the floor, the sphere and (at the top) the sky.
fn scene(w: usize, h: usize) -> Scene {
    let mut floor = Object::new(
        quad(0.0, 2.0),
        Brdf::Lambert(Lambert {
            albedo: Rgb::new(0.5, 0.45, 0.4),
        }),
    );
    floor.catcher = true;
    let ball = Object::new(
        Shape::Sphere(Sphere {
            center: Vec3::new(0.0, 0.0, 0.5),
            radius: 0.5,
        }),
        Brdf::Lambert(Lambert {
            albedo: Rgb::new(0.8, 0.2, 0.2),
        }),
    );
    let l = |x: f64, y: f64| Vec3::new(x, y, 3.0);
    Scene {
        camera: Some(
            Camera::look_at(
                Vec3::new(0.0, -4.0, 1.6),
                Vec3::new(0.0, 0.0, 0.4),
                Vec3::new(0.0, 0.0, 1.0),
                50.0,
                w,
                h,
            )
            .unwrap(),
        ),
        objects: vec![floor, ball],
        lights: vec![AreaLight {
            radiance: Rgb::splat(6.0),
            triangles: vec![
                [l(0.5, -0.5), l(1.5, -0.5), l(1.5, 0.5)],
                [l(0.5, -0.5), l(1.5, 0.5), l(0.5, 0.5)],
            ],
        }],
        background: Rgb::splat(0.3),
        dome: None,
    }
}

fn settings(spp: u32, seed: u64) -> RenderSettings {
    RenderSettings {
        spp,
        max_depth: 4,
        seed,
        ..Default::default()
    }
}

fn env(s: &Scene) -> ConstantEnvironment {
    ConstantEnvironment {
        radiance: s.background,
    }
}

fn full_render(s: &Scene, spp: u32, seed: u64) -> crate::render::RenderOutput {
    render(
        &World::new(s),
        &env(s),
        s.camera.as_ref().unwrap(),
        &settings(spp, seed),
        &|_| {},
        None,
    )
    .unwrap()
}

fn diff(s: &Scene, spp: u32, seed: u64) -> DifferentialOutput {
    differential_render(
        s,
        &env(s),
        s.camera.as_ref().unwrap(),
        &settings(spp, seed),
        None,
        &|_| {},
        None,
    )
    .unwrap()
}

#[test]
fn without_objects_the_composite_is_the_plate_bit_for_bit() {
    let mut s = scene(40, 30);
    s.objects.retain(|o| o.catcher);
    let d = diff(&s, 8, 1);
    let plate = Image::from_fn(40, 30, 3, |x, y, c| (x + 2 * y + c) as f32 * 0.01);
    for mode in [CompositeMode::Additive, CompositeMode::Ratio] {
        let c = composite(&d.layers, &plate, mode).unwrap();
        assert_eq!(c.data, plate.data, "{mode:?}");
    }
    assert!(d.stats.traced_pixels > 0 && d.stats.traced_pixels < d.stats.pixels);
}

#[test]
fn pixels_that_see_nothing_are_not_traced_and_stay_plate() {
    let s = scene(40, 30);
    let d = diff(&s, 4, 1);
    let plate = Image::from_fn(40, 30, 3, |_, _, _| 0.7);
    let c = composite(&d.layers, &plate, CompositeMode::Additive).unwrap();
    // The top row looks at the sky above the floor's far edge.
    let top_untouched = (0..40).all(|x| c.get(x, 0, 0) == 0.7);
    assert!(top_untouched);
    assert!(d.stats.traced_pixels < d.stats.pixels, "{:?}", d.stats);
    assert!(d.stats.paths_without > 0);
}

/// Composite vs truth over pixels fully covered by one thing (edge pixels mix sub-pixel
/// geometry the plate cannot know): the error must be Monte Carlo noise, i.e. its mean square
/// is about the sum of the variances of the three estimates.
#[test]
fn additive_and_ratio_composites_equal_the_truth_within_noise() {
    let (w, h) = (48, 36);
    let s = scene(w, h);
    let truth = full_render(&s, 512, 11);
    let plate = full_render(&s.without_synthetic_objects(), 512, 12);
    let d = diff(&s, 64, 13);
    for mode in [CompositeMode::Additive, CompositeMode::Ratio] {
        let c = composite(&d.layers, &plate.image, mode).unwrap();
        let (mut z2, mut n, mut changed) = (0.0, 0usize, 0usize);
        let (mut abs_err, mut sigma) = (0.0, 0.0);
        for y in 0..h {
            for x in 0..w {
                let a_o = d.layers.beauty.get(x, y, 3);
                let a_c = d.layers.catcher_with.get(x, y, 3);
                let interior = a_o == 1.0 || (a_o == 0.0 && (a_c == 1.0 || a_c == 0.0));
                if !interior {
                    continue;
                }
                for ch in 0..3 {
                    let e = (c.get(x, y, ch) - truth.image.get(x, y, ch)) as f64;
                    let v = (truth.variance.get(x, y, ch)
                        + plate.variance.get(x, y, ch)
                        + d.layers.variance.get(x, y, ch)) as f64;
                    let touched = (c.get(x, y, ch) - plate.image.get(x, y, ch)).abs() > 1e-6;
                    if v > 0.0 {
                        z2 += e * e / v;
                        n += 1;
                    }
                    if touched {
                        changed += 1;
                        abs_err += e.abs();
                        sigma += v.sqrt();
                    }
                }
            }
        }
        let z2 = z2 / n as f64;
        let (abs_err, sigma) = (abs_err / changed as f64, sigma / changed as f64);
        eprintln!("{mode:?}: mean z² {z2:.3} over {n}; changed {changed}: mean |err| {abs_err:.4}, mean σ {sigma:.4}");
        assert!(changed > 300, "too few changed pixels: {changed}");
        // Mean |err| of a Gaussian is 0.8 σ: within 2 σ is "equal within noise".
        assert!(abs_err < 2.0 * sigma, "{mode:?}: {abs_err} vs σ {sigma}");
        if mode == CompositeMode::Additive {
            assert!(z2 < 1.6, "additive: mean z² {z2}");
        }
    }
}

/// The shadow appears: the catcher under the ball is darker with the ball than without.
#[test]
fn the_shadow_darkens_the_catcher_under_the_object() {
    let (w, h) = (48, 36);
    let s = scene(w, h);
    let d = diff(&s, 32, 5);
    let ratio = d.layers.shadow_ratio();
    // The ball hides the light (at x ≈ 1, above) from the floor on its −x side, seen left of
    // the ball in the image; find the darkest ratio over the catcher pixels.
    let mut min_ratio = f32::INFINITY;
    for y in 0..h {
        for x in 0..w {
            if d.layers.catcher_with.get(x, y, 3) == 1.0 {
                min_ratio = min_ratio.min(ratio.get(x, y, 1));
            }
        }
    }
    assert!(min_ratio < 0.6, "no shadow: min ratio {min_ratio}");
    // Far from the ball (the bottom-left corner of the floor) only the ball's faint
    // interreflection changes the floor.
    let far = ratio.get(1, h - 1, 0);
    assert!((far - 1.0).abs() < 0.1, "far ratio {far}");
}

#[test]
fn same_layers_for_any_thread_count() {
    let s = scene(32, 24);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| diff(&s, 6, 9).layers)
    };
    let (a, b) = (run(1), run(4));
    assert_eq!(a.beauty.data, b.beauty.data);
    assert_eq!(a.catcher_with.data, b.catcher_with.data);
    assert_eq!(a.catcher_without.data, b.catcher_without.data);
}

#[test]
fn a_plate_of_the_wrong_size_is_an_error() {
    let s = scene(16, 12);
    let d = diff(&s, 1, 1);
    let e = composite(&d.layers, &Image::new(10, 10, 3), CompositeMode::Additive).unwrap_err();
    assert!(e.contains("10×10") && e.contains("16×12"), "{e}");
}

/// Adaptive sampling puts the samples where the change is noisy: unchanged catcher pixels stop
/// at the minimum, and the composite still matches the truth within its (reported) noise.
#[test]
fn adaptive_sampling_spends_samples_where_the_noise_is() {
    let (w, h) = (48, 36);
    let s = scene(w, h);
    let truth = full_render(&s, 512, 21);
    let plate = full_render(&s.without_synthetic_objects(), 512, 22);
    let a = Adaptive {
        min_spp: 8,
        noise: 0.03,
    };
    let d = differential_render(
        &s,
        &env(&s),
        s.camera.as_ref().unwrap(),
        &settings(256, 23),
        Some(a),
        &|_| {},
        None,
    )
    .unwrap();
    let spp = &d.layers.samples;
    let (mut lo, mut hi) = (u32::MAX, 0u32);
    for y in 0..h {
        for x in 0..w {
            let k = spp.get(x, y, 0) as u32;
            if k > 0 {
                lo = lo.min(k);
                hi = hi.max(k);
            }
        }
    }
    assert_eq!(lo, 8, "some traced pixel needed no more than the minimum");
    assert!(hi > 64, "the noisiest pixels got many samples: max {hi}");
    let mean = d.stats.samples as f64 / d.stats.traced_pixels as f64;
    assert!(mean < 200.0, "mean spp {mean}");
    let c = composite(&d.layers, &plate.image, CompositeMode::Additive).unwrap();
    let (mut z2, mut n) = (0.0, 0);
    for y in 0..h {
        for x in 0..w {
            let a_o = d.layers.beauty.get(x, y, 3);
            let a_c = d.layers.catcher_with.get(x, y, 3);
            if !(a_o == 1.0 || (a_o == 0.0 && a_c == 1.0)) {
                continue;
            }
            for ch in 0..3 {
                let e = (c.get(x, y, ch) - truth.image.get(x, y, ch)) as f64;
                let v = (truth.variance.get(x, y, ch)
                    + plate.variance.get(x, y, ch)
                    + d.layers.variance.get(x, y, ch)) as f64;
                if v > 0.0 {
                    z2 += e * e / v;
                    n += 1;
                }
            }
        }
    }
    let z2 = z2 / n as f64;
    eprintln!("adaptive: spp {lo}..{hi}, mean {mean:.1}; mean z² {z2:.3}");
    assert!(z2 < 2.0, "mean z² {z2}");
}

/// The joint tracer of the catcher samples equals two separate path tracers run from clones of
/// one stream, bit for bit, for every strategy — with a mirror sphere added so paths also part
/// after a specular bounce and meet objects at later vertices.
#[test]
fn joint_with_without_paths_equal_separate_paths() {
    use crate::brdf::Mirror;
    use crate::integrator::Strategy;
    use crate::render::seeded_sampler;
    let mut s = scene(64, 48);
    s.objects.push(Object::new(
        Shape::Sphere(Sphere {
            center: Vec3::new(1.1, 0.3, 0.4),
            radius: 0.4,
        }),
        Brdf::Mirror(Mirror {
            reflectance: Rgb::splat(0.9),
        }),
    ));
    let e = env(&s);
    let with = World::new(&s);
    let without = World::new(&s.without_synthetic_objects());
    let is_catcher: Vec<bool> = s.objects.iter().map(|o| o.catcher).collect();
    let is_synthetic = |m: u32| !is_catcher[m as usize];
    let gen = s.camera.as_ref().unwrap().rays();
    let mut pick = seeded_sampler(11);
    let mut parted = 0;
    for strategy in [Strategy::Mis, Strategy::BrdfOnly, Strategy::LightOnly] {
        let tracer = |world| PathTracer {
            world,
            environment: &e,
            max_depth: 4,
            rr_depth: 2,
            strategy,
        };
        for i in 0..3000u64 {
            let ray = gen.ray(pick.next() * 64.0 - 0.5, pick.next() * 48.0 - 0.5);
            let mut s0 = seeded_sampler(i);
            let (mut s1, mut s2) = (s0.clone(), s0.clone());
            let (lw, lo) =
                tracer(&with).radiance_with_and_without(&without, &is_synthetic, ray, &mut s0);
            let want_w = tracer(&with).radiance(ray, &mut s1);
            let want_o = tracer(&without).radiance(ray, &mut s2);
            assert_eq!((lw, lo), (want_w, want_o), "ray {i} ({strategy:?})");
            // The joint stream continues as the with-objects path's stream did.
            assert_eq!(s0.next(), s1.next());
            parted += usize::from(lw != lo);
        }
    }
    assert!(parted > 300, "too few paths met an object: {parted}");
}
