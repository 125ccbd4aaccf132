//! A solid texture is seen in a render: a textured Lambertian floor under a constant sky
//! reflects ρ·τ(p) of the sky's radiance at every point, so each pixel whose footprint lies in
//! one texture cell equals the texture's factor there.

use vfxgraph_render::scene::{Object, Scene, Shape};
use vfxgraph_render::{
    render, Brdf, Camera, ConstantEnvironment, Lambert, RenderSettings, Rgb, Texture, Vec3, World,
};

fn floor(texture: Option<Texture>) -> Scene {
    let (c, a, b) = (
        Vec3::new(-5.0, 0.0, -5.0),
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 10.0),
    );
    let mut o = Object::new(
        Shape::Triangles {
            triangles: vec![[c, c + a, c + a + b], [c, c + a + b, c + b]],
        },
        Brdf::Lambert(Lambert { albedo: Rgb::WHITE }),
    );
    o.texture = texture;
    Scene {
        camera: Some(
            Camera::look_at(
                Vec3::new(0.0, 3.0, 0.001),
                Vec3::ZERO,
                Vec3::new(0.0, 1.0, 0.0),
                60.0,
                32,
                32,
            )
            .unwrap(),
        ),
        objects: vec![o],
        lights: vec![],
        background: Rgb::WHITE,
        dome: None,
    }
}

#[test]
fn a_textured_floor_renders_its_factor() {
    let tex = Texture::Cells {
        size: 0.4,
        contrast: 0.8,
        seed: 3,
        color: true,
    };
    let scene = floor(Some(tex.clone()));
    let env = ConstantEnvironment {
        radiance: Rgb::WHITE,
    };
    let settings = RenderSettings {
        spp: 256,
        max_depth: 1,
        ..Default::default()
    };
    let out = render(
        &World::new(&scene),
        &env,
        scene.camera.as_ref().unwrap(),
        &settings,
        &|_| {},
        None,
    )
    .unwrap();
    let rays = scene.camera.as_ref().unwrap().rays();
    let hit = |x: f64, y: f64| {
        let r = rays.ray(x, y);
        r.o + r.d * (-r.o.y / r.d.y)
    };
    let (mut checked, mut levels) = (0, Vec::new());
    for y in 0..32 {
        for x in 0..32 {
            let (xf, yf) = (x as f64, y as f64);
            let t = tex.factor(hit(xf, yf));
            let corners = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)];
            if corners
                .iter()
                .any(|(dx, dy)| tex.factor(hit(xf + dx, yf + dy)) != t)
            {
                continue;
            }
            checked += 1;
            levels.push(t.r);
            for (c, want) in [(0, t.r), (1, t.g), (2, t.b)] {
                let got = out.image.get(x, y, c) as f64;
                // Within 5 standard deviations of the pixel's mean (the render's variance).
                let sigma = (out.variance.get(x, y, c) as f64).sqrt();
                assert!(
                    (got - want).abs() < 5.0 * sigma + 1e-3,
                    "pixel {x},{y} ch {c}: {got} vs {want} (σ {sigma})"
                );
            }
        }
    }
    // Many pixels inside cells, with clearly different levels.
    assert!(checked > 400, "{checked}");
    let (lo, hi) = levels
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    assert!(hi - lo > 0.4, "{lo} {hi}");
    // Untextured: a uniform floor of albedo 1 under a unit sky is 1 everywhere.
    let plain = floor(None);
    let out = render(
        &World::new(&plain),
        &env,
        plain.camera.as_ref().unwrap(),
        &settings,
        &|_| {},
        None,
    )
    .unwrap();
    for (v, var) in out.image.data.iter().zip(&out.variance.data) {
        assert!((v - 1.0).abs() < 5.0 * var.sqrt() + 1e-3, "{v} (σ² {var})");
    }
}
