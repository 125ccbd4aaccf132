//! Light-transport tests against analytic truth: the white furnace, the irradiance of a
//! polygonal light (Lambert's closed form), and MIS against its two single strategies.

use std::f64::consts::PI;

use vfxgraph_render::dome::Dome;
use vfxgraph_render::light::LightSampling;
use vfxgraph_render::ray::Ray;
use vfxgraph_render::render::seeded_sampler;
use vfxgraph_render::shape::Sphere;
use vfxgraph_render::*;

fn camera(from: Vec3, at: Vec3, w: usize, h: usize) -> Camera {
    Camera::look_at(from, at, Vec3::new(0.0, 0.0, 1.0), 50.0, w, h).unwrap()
}

/// An 8×8 camera above a y-up floor, looking at the origin.
fn floor_camera() -> Camera {
    Camera::look_at(
        Vec3::new(0.0, 2.0, 3.0),
        Vec3::ZERO,
        Vec3::new(0.0, 1.0, 0.0),
        50.0,
        8,
        8,
    )
    .unwrap()
}

fn quad(c: Vec3, a: Vec3, b: Vec3) -> Vec<[Vec3; 3]> {
    let (p0, p1, p2, p3) = (c - a - b, c + a - b, c + a + b, c - a + b);
    vec![[p0, p1, p2], [p0, p2, p3]]
}

fn lambert(r: f64) -> Brdf {
    Brdf::Lambert(Lambert {
        albedo: Rgb::splat(r),
    })
}

#[test]
fn white_furnace() {
    let l_env = 0.7;
    furnace(
        &ConstantEnvironment {
            radiance: Rgb::splat(l_env),
        },
        l_env,
    );
}

#[test]
fn white_furnace_through_the_dome_sampler() {
    // The same furnace lit by an HDR dome whose image is constant, in a tilted orientation:
    // the dome's importance sampling (2-D CDF, sin θ, pdf in solid angle) and its MIS weights
    // must leave every pixel at the dome's radiance.
    let l_env = 0.7f32;
    let img = vfxgraph_imaging::Image::from_fn(32, 16, 3, |_, _, _| l_env);
    let dome = Dome::new(
        &img,
        nalgebra::Vector3::new(1.0, 0.2, 0.3),
        nalgebra::Vector3::new(0.1, 0.3, 1.0),
    )
    .unwrap();
    furnace(&dome, l_env as f64);
}

/// Albedo-1 diffuse spheres, a mirror sphere and a ground quad inside a uniform environment:
/// every pixel must see the environment's radiance (nothing absorbs, nothing emits).
fn furnace(env: &dyn Environment, l_env: f64) {
    let scene = Scene {
        camera: Some(camera(
            Vec3::new(0.0, -6.0, 2.0),
            Vec3::new(0.0, 0.0, 0.5),
            24,
            16,
        )),
        objects: vec![
            Object {
                shape: Shape::Sphere(Sphere {
                    center: Vec3::new(-1.0, 0.0, 1.0),
                    radius: 1.0,
                }),
                material: lambert(1.0),
                catcher: false,
                texture: None,
            },
            Object {
                shape: Shape::Sphere(Sphere {
                    center: Vec3::new(1.0, 0.3, 0.8),
                    radius: 0.8,
                }),
                material: Brdf::Mirror(Mirror {
                    reflectance: Rgb::WHITE,
                }),
                catcher: false,
                texture: None,
            },
            Object {
                shape: Shape::Triangles {
                    triangles: quad(
                        Vec3::ZERO,
                        Vec3::new(3.0, 0.0, 0.0),
                        Vec3::new(0.0, 3.0, 0.0),
                    ),
                },
                material: lambert(1.0),
                catcher: false,
                texture: None,
            },
        ],
        lights: vec![],
        background: Rgb::splat(l_env),
        dome: None,
    };
    let world = World::new(&scene);
    let settings = RenderSettings {
        spp: 32,
        max_depth: 200,
        ..Default::default()
    };
    let out = render(
        &world,
        env,
        scene.camera.as_ref().unwrap(),
        &settings,
        &|_| {},
        None,
    )
    .unwrap();
    assert_eq!(out.stats.nonfinite, 0);
    let n = out.image.pixel_count();
    let (mut sum, mut var) = (0.0, 0.0);
    for i in 0..n {
        let (m, v) = (
            out.image.data[3 * i + 1] as f64,
            out.variance.data[3 * i + 1] as f64,
        );
        // Each pixel: within 5σ (many pixels), with a floor for zero-variance pixels.
        assert!(
            (m - l_env).abs() <= 5.0 * v.sqrt() + 1e-5,
            "pixel {i}: {m} ± {}",
            v.sqrt()
        );
        sum += m;
        var += v;
    }
    let (mean, se) = (sum / n as f64, var.sqrt() / n as f64);
    assert!(
        (mean - l_env).abs() <= 3.0 * se + 1e-6,
        "furnace mean {mean} ± {se}"
    );
}

/// Irradiance at p (normal n) from a polygon of constant radiance L: Lambert's formula
/// E = L/2 · Σ angle(v_i, v_{i+1}) · n·unit(v_i × v_{i+1}), with v_i = q_i − p.
fn polygon_irradiance(p: Vec3, n: Vec3, poly: &[Vec3], l: f64) -> f64 {
    let mut s = 0.0;
    for i in 0..poly.len() {
        let a = (poly[i] - p).normalized();
        let b = (poly[(i + 1) % poly.len()] - p).normalized();
        let c = a.cross(b);
        s += a.dot(b).clamp(-1.0, 1.0).acos() * n.dot(c.normalized());
    }
    (l / 2.0 * s).abs()
}

#[test]
fn irradiance_from_a_polygonal_light_matches_the_closed_form() {
    // A tilted quad light over a Lambertian floor; the radiance leaving the floor point p is
    // ρ/π · E(p). Estimated with each strategy at depth 1 (direct light only).
    let rho = 0.8;
    let l = 5.0;
    let center = Vec3::new(0.3, -0.2, 1.5);
    let (a, b) = (Vec3::new(0.6, 0.0, 0.2), Vec3::new(0.0, 0.4, -0.1));
    let tris = quad(center, a, b);
    let corners = [
        center - a - b,
        center + a - b,
        center + a + b,
        center - a + b,
    ];
    let p = Vec3::new(0.0, 0.0, 0.0);
    let truth = rho / PI * polygon_irradiance(p, Vec3::new(0.0, 0.0, 1.0), &corners, l);
    let scene = Scene {
        camera: Some(camera(Vec3::new(0.0, -3.0, 3.0), p, 8, 8)),
        objects: vec![Object {
            shape: Shape::Triangles {
                triangles: quad(
                    Vec3::ZERO,
                    Vec3::new(4.0, 0.0, 0.0),
                    Vec3::new(0.0, 4.0, 0.0),
                ),
            },
            material: lambert(rho),
            catcher: false,
            texture: None,
        }],
        lights: vec![AreaLight {
            radiance: Rgb::splat(l),
            triangles: tris,
        }],
        background: Rgb::BLACK,
        dome: None,
    };
    let env = ConstantEnvironment {
        radiance: Rgb::BLACK,
    };
    let from = Vec3::new(0.0, -1.0, 2.0);
    let ray = Ray::new(from, (p - from).normalized());
    let mut light_only_sd = Vec::new();
    for mode in [LightSampling::Area, LightSampling::SolidAngle] {
        let world = World::with_light_sampling(&scene, mode);
        for (strategy, n) in [
            (Strategy::LightOnly, 20_000),
            (Strategy::Mis, 40_000),
            (Strategy::BrdfOnly, 400_000),
        ] {
            let tracer = PathTracer {
                world: &world,
                environment: &env,
                max_depth: 1,
                rr_depth: 100,
                strategy,
            };
            let (m, se) = estimate(&tracer, ray, n, 5);
            assert!(
                (m - truth).abs() < 3.0 * se.max(1e-9),
                "{mode:?} {strategy:?}: {m} ± {se} vs {truth}"
            );
            assert!(
                se < 0.02 * truth,
                "{mode:?} {strategy:?}: estimate too noisy to mean anything ({se})"
            );
            if strategy == Strategy::LightOnly {
                light_only_sd.push(se * (n as f64).sqrt());
            }
        }
    }
    // This light is large and near: sampling its solid angle removes the 1/r² and cos θ_light
    // variation of area sampling, leaving only the receiver's cosine.
    eprintln!(
        "direct light, per-sample sd / mean: area {:.4}, solid angle {:.4}",
        light_only_sd[0] / truth,
        light_only_sd[1] / truth
    );
    assert!(
        light_only_sd[1] < 0.85 * light_only_sd[0],
        "{light_only_sd:?}"
    );
}

#[test]
fn mis_has_the_mean_of_each_single_strategy() {
    // Glossy floor, an occluding sphere, a quad light AND a constant environment, several
    // bounces: MIS, BRDF-only and light-only estimators must agree within noise.
    let scene = Scene {
        camera: Some(camera(Vec3::new(0.0, -3.0, 3.0), Vec3::ZERO, 8, 8)),
        objects: vec![
            Object {
                shape: Shape::Triangles {
                    triangles: quad(
                        Vec3::ZERO,
                        Vec3::new(4.0, 0.0, 0.0),
                        Vec3::new(0.0, 4.0, 0.0),
                    ),
                },
                material: Brdf::BlinnPhong(BlinnPhong {
                    diffuse: Rgb::new(0.5, 0.4, 0.3),
                    specular: Rgb::splat(0.4),
                    exponent: 20.0,
                }),
                catcher: false,
                texture: None,
            },
            Object {
                shape: Shape::Sphere(Sphere {
                    center: Vec3::new(0.4, 0.2, 0.5),
                    radius: 0.5,
                }),
                material: lambert(0.7),
                catcher: false,
                texture: None,
            },
        ],
        lights: vec![AreaLight {
            radiance: Rgb::splat(4.0),
            triangles: quad(
                Vec3::new(-0.5, 0.5, 2.0),
                Vec3::new(0.5, 0.0, 0.0),
                Vec3::new(0.0, 0.5, 0.0),
            ),
        }],
        background: Rgb::splat(0.3),
        dome: None,
    };
    for mode in [LightSampling::Area, LightSampling::SolidAngle] {
        mis_agrees(&World::with_light_sampling(&scene, mode), scene.background);
    }
}

fn mis_agrees(world: &World, background: Rgb) {
    let env = ConstantEnvironment {
        radiance: background,
    };
    let from = Vec3::new(0.0, -2.0, 1.5);
    let target = Vec3::new(-0.2, 0.3, 0.0);
    let ray = Ray::new(from, (target - from).normalized());
    let mut results = Vec::new();
    for (strategy, n) in [
        (Strategy::Mis, 100_000),
        (Strategy::LightOnly, 100_000),
        (Strategy::BrdfOnly, 400_000),
    ] {
        let tracer = PathTracer {
            world,
            environment: &env,
            max_depth: 4,
            rr_depth: 2,
            strategy,
        };
        let mut s = seeded_sampler(7);
        let (mut sum, mut sq) = (0.0, 0.0);
        for _ in 0..n {
            let v = tracer.radiance(ray, &mut s).r;
            sum += v;
            sq += v * v;
        }
        let m = sum / n as f64;
        let se = ((sq / n as f64 - m * m) / (n as f64 - 1.0)).sqrt();
        results.push((strategy, m, se));
    }
    let (_, m0, s0) = results[0];
    for &(st, m, s) in &results[1..] {
        let z = (m - m0) / (s * s + s0 * s0).sqrt();
        assert!(
            z.abs() < 3.5,
            "{st:?} {m} ± {s} vs MIS {m0} ± {s0} (z = {z:.2})"
        );
    }
    // MIS should not be noisier than the worse single strategy.
    assert!(s0 <= results[1].2.max(results[2].2 * 2.0));
}

#[test]
fn same_image_for_any_thread_count() {
    let text = "scene{ camera = view{ from = {0,-4,1}, at = {0,0,0.5}, fov = 60, imgw = 20, imgh = 12 }
      polylight{ color = {3,3,3}, shape = trilist{ {{-1,-1,3},{1,-1,3},{1,1,3}} } }
      object = primobj{ material = plastic{ kd = .5, ks = .4, se = 30 }, shape = sphere{ center = {0,0,0.6}, radius = .6 } }
      object = polyobj{ material = plastic{ kd = .8 }, shape = trilist{ {{-5,-5,0},{5,-5,0},{5,5,0}}, {{-5,-5,0},{5,5,0},{-5,5,0}} } } }";
    let scene = parse_scn(text).unwrap();
    let world = World::new(&scene);
    let env = ConstantEnvironment {
        radiance: Rgb::BLACK,
    };
    let cam = scene.camera.as_ref().unwrap();
    let settings = RenderSettings {
        spp: 8,
        tile: 7,
        seed: 42,
        ..Default::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render(&world, &env, cam, &settings, &|_| {}, None).unwrap())
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.image, b.image);
    assert!(a.image.data.iter().any(|&v| v > 0.0));
    // Another seed gives another image.
    let other = render(
        &world,
        &env,
        cam,
        &RenderSettings {
            seed: 43,
            ..settings
        },
        &|_| {},
        None,
    )
    .unwrap();
    assert_ne!(a.image, other.image);
    // Cancellation.
    let flag = std::sync::atomic::AtomicBool::new(true);
    assert_eq!(
        render(&world, &env, cam, &settings, &|_| {}, Some(&flag)).unwrap_err(),
        RenderError::Cancelled
    );
}

/// A smooth, strongly non-uniform dome: a bright warm blob high in the sky over a dim
/// gradient (y-up world, zenith on the top row).
fn blob_dome() -> Dome {
    let (w, h) = (64usize, 32usize);
    let img = vfxgraph_imaging::Image::from_fn(w, h, 3, |x, y, c| {
        let (dx, dy) = (x as f32 - 40.0, y as f32 - 9.0);
        let blob = 30.0 * (-(dx * dx + dy * dy) / 18.0).exp();
        let sky = 0.2 + 0.3 * (1.0 - y as f32 / h as f32);
        (sky + blob) * [1.0, 0.8, 0.6][c]
    });
    Dome::y_up(&img).unwrap()
}

/// Mean and standard error of `n` path estimates (green channel) along `ray`.
fn estimate(tracer: &PathTracer, ray: Ray, n: usize, seed: u64) -> (f64, f64) {
    let mut s = seeded_sampler(seed);
    let (mut sum, mut sq) = (0.0, 0.0);
    for _ in 0..n {
        let v = tracer.radiance(ray, &mut s).g;
        sum += v;
        sq += v * v;
    }
    let m = sum / n as f64;
    (m, ((sq / n as f64 - m * m) / (n as f64 - 1.0)).sqrt())
}

#[test]
fn dome_direct_light_matches_the_brute_force_irradiance() {
    // A Lambertian floor (normal +y) under a non-uniform dome, direct light only: the radiance
    // leaving it is rho/pi * E, E summed over every texel. Dome NEE, MIS and BRDF-only agree
    // with it; dome NEE is the least noisy.
    let dome = blob_dome();
    let rho = 0.8;
    let big = 50.0;
    let floor = quad(
        Vec3::ZERO,
        Vec3::new(big, 0.0, 0.0),
        Vec3::new(0.0, 0.0, big),
    );
    let scene = Scene {
        camera: Some(floor_camera()),
        objects: vec![Object::new(
            Shape::Triangles { triangles: floor },
            lambert(rho),
        )],
        lights: vec![],
        background: Rgb::BLACK,
        dome: None,
    };
    let world = World::new(&scene);
    let truth = rho / PI * dome.irradiance_brute_force(&nalgebra::Vector3::y()).y;
    let from = Vec3::new(0.0, 1.0, 2.0);
    let ray = Ray::new(from, (Vec3::ZERO - from).normalized());
    let mut ses = Vec::new();
    for (strategy, n) in [
        (Strategy::LightOnly, 40_000),
        (Strategy::Mis, 40_000),
        (Strategy::BrdfOnly, 400_000),
    ] {
        let tracer = PathTracer {
            world: &world,
            environment: &dome,
            max_depth: 1,
            rr_depth: 100,
            strategy,
        };
        let (m, se) = estimate(&tracer, ray, n, 11);
        // Bilinear lookup vs texel centres: allow 0.5 % on top of 3 sigma.
        assert!(
            (m - truth).abs() < 3.0 * se + 5e-3 * truth,
            "{strategy:?}: {m} ± {se} vs {truth}"
        );
        ses.push(se * (n as f64).sqrt());
    }
    // Per-sample noise: importance-sampled dome beats cosine sampling on this peaked dome.
    assert!(ses[0] < 0.5 * ses[2], "per-sample sd {ses:?}");
}

#[test]
fn dome_nee_has_the_mean_of_brdf_sampling() {
    // Glossy floor, an occluding diffuse sphere and a mirror sphere under the non-uniform dome,
    // several bounces: MIS (dome NEE + BRDF sampling) and BRDF-only agree within noise.
    let dome = blob_dome();
    let floor = quad(
        Vec3::ZERO,
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 4.0),
    );
    let scene = Scene {
        camera: Some(floor_camera()),
        objects: vec![
            Object::new(
                Shape::Triangles { triangles: floor },
                Brdf::BlinnPhong(BlinnPhong {
                    diffuse: Rgb::new(0.5, 0.4, 0.3),
                    specular: Rgb::splat(0.4),
                    exponent: 20.0,
                }),
            ),
            Object::new(
                Shape::Sphere(Sphere {
                    center: Vec3::new(0.3, 0.5, -0.2),
                    radius: 0.5,
                }),
                lambert(0.7),
            ),
            Object::new(
                Shape::Sphere(Sphere {
                    center: Vec3::new(-0.9, 0.4, 0.1),
                    radius: 0.4,
                }),
                Brdf::Mirror(Mirror {
                    reflectance: Rgb::splat(0.9),
                }),
            ),
        ],
        lights: vec![],
        background: Rgb::BLACK,
        dome: None,
    };
    let world = World::new(&scene);
    let from = Vec3::new(0.2, 1.2, 2.0);
    let ray = Ray::new(from, (Vec3::new(0.0, 0.0, 0.3) - from).normalized());
    let run = |strategy, n| {
        let tracer = PathTracer {
            world: &world,
            environment: &dome,
            max_depth: 4,
            rr_depth: 2,
            strategy,
        };
        estimate(&tracer, ray, n, 21)
    };
    let (m0, s0) = run(Strategy::Mis, 100_000);
    let (m1, s1) = run(Strategy::BrdfOnly, 400_000);
    let (m2, s2) = run(Strategy::LightOnly, 100_000);
    for (name, m, s) in [("brdf-only", m1, s1), ("light-only", m2, s2)] {
        let z = (m - m0) / (s * s + s0 * s0).sqrt();
        assert!(
            z.abs() < 3.5,
            "{name} {m} ± {s} vs MIS {m0} ± {s0} (z = {z:.2})"
        );
    }
    assert!(m0 > 0.0 && s0 < 0.02 * m0, "{m0} ± {s0}");
}
